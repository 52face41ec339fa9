#!/usr/bin/env bash
# Long run over DDS: a simulated drive of MINUTES replayed at real time into ppf_node (separate
# processes, the project's SHM+UDP profile), the node's resident memory sampled every few seconds.
# Checks that nothing is lost, odometry comes for every scan after initialization, the trajectory
# meets an APE bound, and memory is flat after warm-up: its growth over the second half of the run
# stays under --max-growth-mb. With a node built with AddressSanitizer (--node BIN, e.g. from
# `scripts/sanitize.sh asan`), LeakSanitizer runs at the node's exit and any leak fails the run.
#
#   scripts/soak.sh [--minutes 30] [--lidar vlp16] [--scene urban] [--mode ppf]
#                   [--node BIN] [--max-growth-mb 16] [--ape-max 1.0] [--out DIR] [--keep-bag]
#
# Needs the built workspace (source install/setup.bash). Prints a table of the RSS samples per
# minute and a SOAK_RESULT line; exits 1 if a check fails. The bag takes ~7.5 MB per second of
# VLP-16 drive (13 GB for 30 minutes) under DIR and is deleted at the end unless --keep-bag.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
minutes=30 lidar=vlp16 scene=urban mode=ppf node_bin="" max_growth_mb=16 ape_max=1.0
out="" keep_bag=0 domain=$(( 150 + $$ % 50 ))
while [ $# -gt 0 ]; do
  case "$1" in
    --minutes) minutes="$2"; shift ;;
    --lidar) lidar="$2"; shift ;;
    --scene) scene="$2"; shift ;;
    --mode) mode="$2"; shift ;;
    --node) node_bin="$2"; shift ;;
    --max-growth-mb) max_growth_mb="$2"; shift ;;
    --ape-max) ape_max="$2"; shift ;;
    --out) out="$2"; shift ;;
    --keep-bag) keep_bag=1 ;;
    --domain) domain="$2"; shift ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "soak.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done

for tool in ppf_sim ppf_node ppf_replay ppf_eval; do
  command -v "$tool" >/dev/null || { echo "soak.sh: $tool not on PATH: source install/setup.bash" >&2; exit 2; }
done
node_bin=${node_bin:-$(command -v ppf_node)}
out=${out:-$(mktemp -d /tmp/ppf_soak.XXXXXX)}
mkdir -p "$out"
log() { printf '[soak %s] %s\n' "$(date +%H:%M:%S)" "$*"; }

duration_s=$(awk -v m="$minutes" 'BEGIN { printf "%d", m * 60 + 3 }')
bag="$out/bag"
if [ ! -f "$bag/metadata.yaml" ]; then
  log "simulating ${duration_s} s: $scene, $lidar -> $bag"
  ppf_sim --scene "$scene" --lidar "$lidar" --duration "$duration_s" --seed 11 --storage mcap \
    --out "$bag" >"$out/sim.log" 2>&1 || { tail "$out/sim.log" >&2; exit 1; }
fi

cat >"$out/node.yaml" <<EOF
dds: {domain_id: $domain, profiles_file: "$ROOT/config/dds/shm_udp.xml", profile_name: ppf_shm_udp}
core: {config_file: "$ROOT/config/$lidar.yaml", calibration_file: "$bag/calibration.yaml", mode: $mode}
trajectory: {tum_file: "$out/node.tum"}
outputs: {path: true, skeleton_planes: true}
EOF

# LeakSanitizer reports at exit (an ASan build); a leak makes the node exit non-zero.
ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:halt_on_error=1}" \
  "$node_bin" --config "$out/node.yaml" >"$out/node.log" 2>&1 &
node_pid=$!
cleanup() { kill -INT "$node_pid" 2>/dev/null || true; }
trap cleanup EXIT
for _ in $(seq 100); do grep -q "points: 1 publisher" "$out/node.log" 2>/dev/null && break; sleep 0.2; done

sample_rss() {
  echo "elapsed_s,rss_kb" >"$out/rss.csv"
  local t0
  t0=$(date +%s)
  while kill -0 "$node_pid" 2>/dev/null; do
    awk -v t="$(( $(date +%s) - t0 ))" '/^VmRSS/ { print t "," $2 }' "/proc/$node_pid/status" \
      >>"$out/rss.csv" 2>/dev/null || true
    sleep 5
  done
}
sample_rss &
sampler_pid=$!

log "replaying at real time into $node_bin (domain $domain, mode $mode)"
ppf_replay --bag "$bag" --domain "$domain" --profiles "$ROOT/config/dds/shm_udp.xml" \
  --wait-matched 30 --delay 3 >"$out/replay.log" 2>&1 || { tail "$out/replay.log" >&2; exit 1; }
sleep 3  # the node works through what it has queued
kill -INT "$node_pid"
node_rc=0
wait "$node_pid" || node_rc=$?
trap - EXIT
wait "$sampler_pid" 2>/dev/null || true

summary=$(grep -h "^PPF_NODE_SUMMARY" "$out/node.log" | tail -1)
field() { echo "$summary" | tr ' ' '\n' | awk -F= -v k="$1" '$1 == k { print $2 }'; }
sent=$(sed -n 's|.*/points=\([0-9]*\).*|\1|p' "$out/replay.log" | tail -1)
ape=$(ppf_eval ape --ref "$bag/groundtruth.tum" --est "$out/node.tum" --align se3 2>&1 |
        awk '/rmse/ { for (i = 1; i <= NF; i++) if ($i ~ /^[0-9.]+$/) { print $i; exit } }')
ape_posyaw=$(ppf_eval ape --ref "$bag/groundtruth.tum" --est "$out/node.tum" --align posyaw 2>&1 |
        awk '/rmse/ { for (i = 1; i <= NF; i++) if ($i ~ /^[0-9.]+$/) { print $i; exit } }')

# Memory: per minute, and the growth over the second half (the warm-up is the first half).
echo
echo "| minute | node RSS MB |"
echo "|---|---|"
awk -F, 'NR > 1 { m = int($1 / 60); last[m] = $2 } END { for (m in last) printf "| %d | %.1f |\n", m, last[m] / 1024 }' \
  "$out/rss.csv" | sort -t'|' -k2 -n
read -r half_kb end_kb max_kb < <(awk -F, 'NR > 1 { t[NR] = $1; r[NR] = $2; n = NR }
  END { mid = t[n] / 2; for (i = 2; i <= n; i++) { if (t[i] <= mid) h = r[i]; if (r[i] > mx) mx = r[i] }
        print h, r[n], mx }' "$out/rss.csv")
growth_mb=$(awk -v a="$half_kb" -v b="$max_kb" 'BEGIN { printf "%.1f", (b - a) / 1024 }')

fail=()
[ "$node_rc" -eq 0 ] || fail+=("node exit status $node_rc (LeakSanitizer or crash: see $out/node.log)")
[ "$(field scans_lost)" = 0 ] || fail+=("scans_lost=$(field scans_lost)")
[ "$(field imu_lost)" = 0 ] || fail+=("imu_lost=$(field imu_lost)")
[ "$(field resets)" = 0 ] || fail+=("resets=$(field resets)")
[ "$(field scans_received)" = "$sent" ] || fail+=("received $(field scans_received) of $sent scans")
expected=$(( $(field scans_processed) - $(field scans_initializing) ))
[ "$(field odometry_published)" = "$expected" ] || fail+=("odometry $(field odometry_published) of $expected")
awk -v g="$growth_mb" -v m="$max_growth_mb" 'BEGIN { exit !(g <= m) }' ||
  fail+=("RSS grew ${growth_mb} MB over the second half (bound ${max_growth_mb})")
awk -v a="${ape:-inf}" -v m="$ape_max" 'BEGIN { exit !(a <= m) }' || fail+=("APE ${ape:-?} m > $ape_max")

echo
echo "SOAK_RESULT minutes=$minutes mode=$mode scans_sent=$sent scans_received=$(field scans_received)" \
  "odometry=$(field odometry_published) dropped=$(field scans_dropped) lost=$(field scans_lost)" \
  "imu_lost=$(field imu_lost) resets=$(field resets) rss_half_mb=$(( half_kb / 1024 ))" \
  "rss_max_mb=$(( max_kb / 1024 )) rss_end_mb=$(( end_kb / 1024 )) growth_second_half_mb=$growth_mb" \
  "ape_se3_m=$ape ape_posyaw_m=$ape_posyaw node_exit=$node_rc"
[ "$keep_bag" -eq 1 ] || rm -rf "$bag"
if [ ${#fail[@]} -gt 0 ]; then
  printf 'SOAK FAILED: %s\n' "${fail[@]}" >&2
  exit 1
fi
echo "SOAK PASSED ($out)"
