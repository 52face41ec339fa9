#!/bin/sh
# ppf_offline on a ROS 1 bag gives the same trajectory as on the MCAP of the same sequence.
# ppf_sim writes one seeded sequence twice (sqlite3 and MCAP: same seed, same bytes); Debian's
# rosbag turns the .db3 into a ROS 1 bag in each chunk compression (db3_to_ros1_bag.py, its own
# CDR decoding, installed by ppf_bag); every ppf_offline trajectory must equal the MCAP one byte
# for byte.
# usage: ros1_offline_equivalence.sh PPF_SIM PPF_OFFLINE CONFIG_DIR WORKDIR DB3_TO_ROS1_BAG_PY
# Exit 77 (CTest SKIP_RETURN_CODE) when /usr/bin/python3 has no rosbag.
set -eu
sim=$1 offline=$2 config=$3 work=$4 db3_to_ros1=$5
if ! /usr/bin/python3 -c 'import rosbag, roslz4, sensor_msgs.msg' 2>/dev/null; then
  echo "SKIP: needs Debian's python3-rosbag and python3-sensor-msgs for /usr/bin/python3" \
       "(apt-get install -y python3-rosbag python3-sensor-msgs; scripts/setup.sh installs them)"
  exit 77
fi
rm -rf "$work"
mkdir -p "$work"
cd "$work"
seq="--scene indoor --lidar vlp16 --duration 6 --seed 3"
"$sim" --out db3 $seq --storage sqlite3 >/dev/null
"$sim" --out mcap $seq --storage mcap >/dev/null
run() {
  "$offline" --bag "$1" --config "$config/vlp16.yaml" --config mcap/calibration.yaml --mode knn \
    --out "$2" >"$2.log" 2>&1 || { cat "$2.log"; exit 1; }
}
run mcap mcap.tum
[ "$(wc -l <mcap.tum)" -ge 40 ] || { echo "FAIL: only $(wc -l <mcap.tum) poses from the MCAP"; exit 1; }
for c in none bz2 lz4; do
  /usr/bin/python3 "$db3_to_ros1" db3/db3_0.db3 "$c.bag" "$c"
  run "$c.bag" "$c.tum"
  if cmp -s mcap.tum "$c.tum"; then
    echo "same trajectory from the $c ROS 1 bag as from the MCAP ($(wc -l <"$c.tum") poses)"
  else
    echo "FAIL: the $c ROS 1 bag gives another trajectory than the MCAP"
    diff mcap.tum "$c.tum" | head -5
    exit 1
  fi
done
