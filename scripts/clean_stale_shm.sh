#!/usr/bin/env bash
# Removes Fast DDS shared-memory files left in /dev/shm by processes that were killed (a failed
# test, a crash): they can collide with the ports of new participants. Files of live participants
# stay, including a ROS 2 graph or a replay running beside the tests on this machine.
#
# Fast DDS keeps one name in several files: the segment or port (mapped while in use), its "_el"
# lock file (held open by its owner, never mapped) and, for a port, "sem.<name>_mutex" (neither
# mapped nor open between uses). Deleting the lock or the semaphore of a live port cuts its
# readers off silently: a live ppf_node stopped receiving two seconds after an older version of
# this cleanup ran. So a name is stale only when none of its files is mapped or open anywhere.
#
#   scripts/clean_stale_shm.sh [--dry-run]     (prints what it removes)
set -uo pipefail
dry=0
[ "${1:-}" = "--dry-run" ] && dry=1

in_use=$( { cat /proc/[0-9]*/maps 2>/dev/null | awk '{print $6}';
            find /proc/[0-9]*/fd -lname '/dev/shm/*' -printf '%l\n' 2>/dev/null; } |
          grep '^/dev/shm/' | sort -u)

base_of() {  # /dev/shm/sem.fastrtps_port7411_mutex, ..._el, ... -> fastrtps_port7411
  local b="${1#/dev/shm/}"
  b="${b#sem.}"
  b="${b%_mutex}"
  b="${b%_el}"
  echo "$b"
}

declare -A live=()
while IFS= read -r f; do
  [ -n "$f" ] && live["$(base_of "$f")"]=1
done <<<"$in_use"

for f in /dev/shm/fastrtps_* /dev/shm/sem.fastrtps_*; do
  [ -e "$f" ] || continue
  [ -n "${live[$(base_of "$f")]:-}" ] && continue
  echo "stale: $f"
  [ "$dry" -eq 1 ] || rm -f "$f"
done
exit 0
