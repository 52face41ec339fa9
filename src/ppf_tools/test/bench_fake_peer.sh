#!/bin/sh
# ppf_bench --peers with fake runners in a temporary directory: rko_lio_runner writes a --times
# file (comment line, then per-scan "wall_ms cpu_ms"; median 4.00 of 3, 4, 9) and records the
# arguments it got; kiss_icp_runner fails with exit 3. Prints the bench's output, its exit code,
# then what the fake runner received.
bench=$1 workdir=$2 offline=$3
d=$(mktemp -d) || exit 1
cat > "$d/rko_lio_runner" <<'RUNNER'
#!/bin/sh
bag=$1 out=$2
shift 2
threads= times= extr=
while [ $# -gt 0 ]; do
  case $1 in
    --threads) threads=$2; shift 2 ;;
    --times) times=$2; shift 2 ;;
    --extrinsic) extr="$2 $3 $4 $5"; shift 5 ;;
    *) echo "unexpected $1"; exit 2 ;;
  esac
done
[ -f "$bag/metadata.yaml" ] && grep -q 'storage_identifier: sqlite3' "$bag/metadata.yaml" || exit 4
printf '# fake: reg_ms reg_cpu_ms\n9.0 18.0\n3.0 6.0\n4.0 8.0\n' > "$times"
: > "$out"
echo "fake rko_lio_runner: $bag --threads $threads --extrinsic $extr" > "$(dirname "$0")/args"
RUNNER
printf '#!/bin/sh\nexit 3\n' > "$d/kiss_icp_runner"
chmod +x "$d/rko_lio_runner" "$d/kiss_icp_runner"
"$bench" --sequences indoor:vlp16 --duration 2 --threads 2 --workdir "$workdir" \
  --ppf-offline "$offline" --peers "$d" 2>&1
echo "exit $?"
cat "$d/args" 2>&1
rm -rf "$d"
