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
OUT="${PPF_DEMO_OUT:-out/demo}"
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
  echo "ppf_sim is not built yet: nothing to run. (See README: Status.)"
  exit 1
fi
rm -rf "$SEQ"
ppf_sim --scene "$SCENE" --lidar "$LIDAR" --duration "$DURATION" --seed 1 --storage mcap --out "$SEQ"
ppf_bag_info "$SEQ" 2>/dev/null || true

CONFIG="config/${LIDAR}.yaml"
[ -f "$CONFIG" ] || CONFIG="config/node.yaml"

if have ppf_node && have ppf_replay && have ppf_record; then
  step "DDS: ppf_replay -> ppf_node -> ppf_record (real time, ${DURATION} s)"
  DOMAIN=$(( ( $$ % 200 ) + 20 ))
  export FASTRTPS_DEFAULT_PROFILES_FILE="$ROOT/config/dds/shm_udp.xml"
  rm -rf "$OUT/recorded" "$OUT/node_traj.tum"
  ppf_record --domain "$DOMAIN" --topics /odometry /skeleton_planes --out "$OUT/recorded" --storage mcap &
  rec=$!
  ppf_node --config "$ROOT/config/node.yaml" --domain "$DOMAIN" --lidar-config "$ROOT/$CONFIG" \
    --trajectory "$OUT/node_traj.tum" &
  node=$!
  sleep 2
  ppf_replay --domain "$DOMAIN" --bag "$SEQ"
  sleep 2
  kill -INT "$node"; wait "$node" || true
  kill -INT "$rec"; wait "$rec" || true
  ppf_bag_info "$OUT/recorded" 2>/dev/null || true
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
