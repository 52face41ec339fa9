#!/bin/sh
# ppf_bench --peers where ppf_sim is not on PATH (a workspace not sourced): the MCAP sequence is
# there already, the sqlite3 copy for the peers cannot be made, and the note says why (the exec
# error from ppf_sim's log) while our table still prints. Prints the bench's output, its exit
# code and the log.
bench=$1 sim=$2 offline=$3
d=$(mktemp -d) || exit 1
mkdir "$d/peers" "$d/work"
for runner in rko_lio_runner kiss_icp_runner; do
  printf '#!/bin/sh\nexit 3\n' > "$d/peers/$runner"
  chmod +x "$d/peers/$runner"
done
"$sim" --scene indoor --lidar vlp16 --duration 2 --seed 1 --storage mcap \
  --out "$d/work/indoor_vlp16_2s" > "$d/sim.log" 2>&1 || { cat "$d/sim.log"; exit 1; }
PATH=/usr/bin:/bin "$bench" --sequences indoor:vlp16 --duration 2 --threads 2 \
  --workdir "$d/work" --ppf-offline "$offline" --peers "$d/peers" 2>&1
echo "exit $?"
cat "$d/work/indoor_vlp16_2s_sqlite3.sim.log"
rm -rf "$d"
