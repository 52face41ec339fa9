#!/usr/bin/env bash
# The main job, end to end, on an embedded default (no downloads):
#   1. set up and build (scripts/setup.sh)
#   2. generate a simulated urban drive with ground truth (ppf_sim)
#   3. replay it over DDS (ppf_replay) into the odometry node (ppf_node), record what the node
#      publishes (ppf_record), and score the trajectory against ground truth (ppf_eval)
#   4. run the same sequence offline in both modes (ppf_offline --mode knn / ppf) and compare
#
# Options (environment): PPF_DEMO_OUT (default out/demo), PPF_DEMO_SCENE (urban),
# PPF_DEMO_LIDAR (hdl32), PPF_DEMO_DURATION (20 s), PPF_DEMO_SKIP_SETUP=1.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
OUT="$(realpath -m "${PPF_DEMO_OUT:-out/demo}")"
SCENE="${PPF_DEMO_SCENE:-urban}"
LIDAR="${PPF_DEMO_LIDAR:-hdl32}"
DURATION="${PPF_DEMO_DURATION:-20}"

step() { printf '\n\033[1m== %s\033[0m\n' "$*"; }
have() { command -v "$1" >/dev/null 2>&1; }

if [ "${PPF_DEMO_SKIP_SETUP:-0}" != 1 ]; then
  step "setup and build"
  scripts/setup.sh
fi
set +u
# shellcheck disable=SC1091
source install/setup.bash
set -u
mkdir -p "$OUT"
SEQ="$OUT/${SCENE}_${LIDAR}"

step "simulate: ${DURATION} s ${SCENE} drive, ${LIDAR} LiDAR, 200 Hz IMU -> $SEQ"
if ! have ppf_sim; then
  echo "ppf_sim is not built yet: nothing to run (scripts/setup.sh builds it)."
  exit 1
fi
rm -rf "$SEQ"
ppf_sim --scene "$SCENE" --lidar "$LIDAR" --duration "$DURATION" --seed 1 --storage mcap --out "$SEQ"
ppf_bag_info "$SEQ" 2>/dev/null || true

CONFIG="config/${LIDAR}.yaml"
[ -f "$CONFIG" ] || { echo "no preset $CONFIG"; exit 1; }

if have ppf_node && have ppf_replay && have ppf_record; then
  step "DDS: ppf_replay -> ppf_node (mode ppf) -> ppf_record, real time, ${DURATION} s"
  DOMAIN=$(( ( $$ % 100 ) + 100 ))   # a private DDS domain: the demo must not disturb a ROS graph
  PROFILES="$ROOT/config/dds/shm_udp.xml"
  PROFILE=ppf_shm_udp
  DDS=(--domain "$DOMAIN" --profiles "$PROFILES" --profile "$PROFILE")
  rm -rf "$OUT/recorded" "$OUT/node_traj.tum"
  cat >"$OUT/node_demo.yaml" <<YAML
# Written by scripts/demo.sh: config/node.yaml defaults plus the demo's domain and files.
dds: {domain_id: $DOMAIN, profiles_file: "$PROFILES", profile_name: $PROFILE}
core: {config_file: "$ROOT/$CONFIG", calibration_file: "$SEQ/calibration.yaml", mode: ppf}
trajectory: {tum_file: "$OUT/node_traj.tum"}
YAML
  ppf_record --topics /odometry /skeleton_planes --out "$OUT/recorded" --storage mcap "${DDS[@]}" \
    >"$OUT/record.log" 2>&1 &
  rec=$!
  ppf_node --config "$OUT/node_demo.yaml" >"$OUT/node.log" 2>&1 &
  node=$!
  sleep 2
  ppf_replay --bag "$SEQ" --wait-matched 15 "${DDS[@]}"
  sleep 1
  kill -INT "$node" 2>/dev/null || true
  wait "$node" || true
  step "ppf_node log (periodic status lines and the final summary)"
  tail -n 12 "$OUT/node.log"
  kill -INT "$rec" 2>/dev/null || true
  wait "$rec" || true
  step "what the node published (recorded with ppf_record)"
  ppf_bag_info "$OUT/recorded" || true
  if have ppf_eval && [ -s "$OUT/node_traj.tum" ]; then
    step "accuracy of the node's odometry vs ground truth"
    ppf_eval ape --ref "$SEQ/groundtruth.tum" --est "$OUT/node_traj.tum" --align se3
  fi
else
  step "DDS node: not built yet (ppf_node/ppf_replay/ppf_record missing), skipping"
fi

if have ppf_offline; then
  for mode in knn ppf; do
    step "offline, --mode $mode"
    ppf_offline --bag "$SEQ" --config "$CONFIG" --config "$SEQ/calibration.yaml" --mode "$mode" \
      --out "$OUT/offline_${mode}.tum" --stats "$OUT/offline_${mode}.csv"
    if have ppf_eval; then
      ppf_eval ape --ref "$SEQ/groundtruth.tum" --est "$OUT/offline_${mode}.tum" --align se3
    fi
  done
else
  step "offline runner: not built yet (ppf_offline missing), skipping"
fi
step "done: outputs in $OUT"
