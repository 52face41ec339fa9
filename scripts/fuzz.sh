#!/usr/bin/env bash
# Runs every libFuzzer target (fuzz/) for a bounded time each, from the ASan+UBSan build that
# `scripts/sanitize.sh asan` leaves in install-asan/:
#
#   scripts/fuzz.sh [SECONDS_EACH] [TARGET...]    default: 45 s each, all targets
#
# Each target starts from its committed seeds (fuzz/corpus/<target>) and any inputs that once
# crashed it (fuzz/regressions/<target>); what it learns is kept in fuzz-out/corpus/<target>, so
# a local rerun continues where the last one stopped (CI starts fresh). A crash, leak, sanitizer
# report, timeout (> 10 s for one input) or allocation beyond 2 GB fails the target, and the
# input that did it is left in fuzz-out/crashes/ (add it to fuzz/regressions/<target>/ once
# fixed). Prints one line per target with libFuzzer's figures: executions, coverage (cov: edges
# reached, ft: features) and corpus size. Exit status: non-zero if any target failed.
# PPF_STAGE_RESULTS=<file>: also append "PASS|FAIL <seconds> fuzz <target>" lines for
# scripts/test_summary.py.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
seconds="${1:-45}"
shift || true
bin_dir="install-asan/ppf_fuzz/lib/ppf_fuzz"
if [ ! -d "$bin_dir" ]; then
  echo "fuzz: no fuzz targets in $bin_dir: run scripts/sanitize.sh asan first" >&2
  [ -n "${PPF_STAGE_RESULTS:-}" ] && echo "FAIL 0 fuzz no fuzz targets built" >>"$PPF_STAGE_RESULTS"
  exit 1
fi
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for d in fuzz/corpus/*/; do targets+=("$(basename "$d")"); done
fi

set +u
# shellcheck disable=SC1091
source install-asan/setup.bash
set -u
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
mkdir -p fuzz-out/crashes

# One target: its line (and, on failure, the log's tail) into fuzz-out/<target>.result, its stage
# line into fuzz-out/<target>.stage; the caller prints them in order.
run_target() {
  local t="$1" exe="$bin_dir/$1" start rc elapsed execs last cov ft corp status
  local result="fuzz-out/$t.result"
  if [ ! -x "$exe" ]; then
    echo "FAIL  $t: not built ($exe)" >"$result"
    echo "FAIL 0 fuzz $t" >"fuzz-out/$t.stage"
    return
  fi
  mkdir -p "fuzz-out/corpus/$t"
  local inputs=("fuzz-out/corpus/$t" "fuzz/corpus/$t")
  [ -d "fuzz/regressions/$t" ] && inputs+=("fuzz/regressions/$t")
  start=$(date +%s)
  # timeout: a hang inside libFuzzer's own shutdown must not stall CI; -timeout bounds one input.
  timeout --kill-after=10 $((seconds + 120)) "$exe" -max_total_time="$seconds" -timeout=10 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="fuzz-out/crashes/$t-" \
    "${inputs[@]}" >"fuzz-out/$t.log" 2>&1
  rc=$?
  elapsed=$(( $(date +%s) - start ))
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "fuzz-out/$t.log" | tail -1)
  last=$(grep -E '^#[0-9]+' "fuzz-out/$t.log" | tail -1)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
  corp=$(sed -n 's/.* corp: \([0-9]*\/[0-9]*[a-zA-Z]*\).*/\1/p' <<<"$last")
  status=PASS
  [ $rc -eq 0 ] || status=FAIL
  printf '%s  %-22s %4d s  %10s execs  cov %6s  ft %6s  corpus %s\n' "$status" "$t" "$elapsed" \
    "${execs:-?}" "${cov:-?}" "${ft:-?}" "${corp:-?}" >"$result"
  if [ "$status" = FAIL ]; then
    { echo "----- $t (exit $rc), last lines of fuzz-out/$t.log -----"; tail -40 "fuzz-out/$t.log"; } \
      >>"$result"
  fi
  echo "$status $elapsed fuzz $t" >"fuzz-out/$t.stage"
}

# Targets run PPF_FUZZ_JOBS at a time (default 2, one per core of a CI machine): each is a
# single-threaded process, so two side by side keep each one's seconds of fuzzing and halve the
# stage's wall time.
jobs="${PPF_FUZZ_JOBS:-2}"
running=0
for t in "${targets[@]}"; do
  rm -f "fuzz-out/$t.result" "fuzz-out/$t.stage"
  run_target "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then
    wait -n
    running=$((running - 1))
  fi
done
wait

failed=0
for t in "${targets[@]}"; do
  cat "fuzz-out/$t.result"
  grep -q '^PASS' "fuzz-out/$t.stage" || failed=1
  [ -n "${PPF_STAGE_RESULTS:-}" ] && cat "fuzz-out/$t.stage" >>"$PPF_STAGE_RESULTS"
done
exit $failed
