#!/usr/bin/env bash
# Builds docker/Dockerfile with a real engine (rootful podman: a Docker daemon cannot run on these
# machines) and runs docker/compose.yaml's scenario (ppf_node + a replay of a simulated sequence),
# then records the node's odometry from a third container and counts it. From a fresh Debian 12
# machine: installs podman, runc, docker-compose and debootstrap, and makes the debian:12 base
# image locally with debootstrap (no registry is reachable here).
#
# The compose file is run by docker-compose talking to podman's Docker-compatible API socket,
# which is how the Docker engines users have read it. Debian 12's podman-compose (1.0.3) cannot
# run it: it adds a default network next to `network_mode: host`, which podman refuses
# (containers/podman-compose issues 397 and 961).
#
#   scripts/container_check.sh [--keep] [--record-seconds S]
#
# Environment: PPF_BUILD_JOBS bounds the image build's compile jobs (default: all cores).
# Prints build time, image size and the odometry count; exits non-zero if the image does not
# build, a container fails, or no odometry arrives. --keep leaves the compose services running.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

keep=0
record_s=40
while [ $# -gt 0 ]; do
  case "$1" in
    --keep) keep=1 ;;
    --record-seconds) record_s="$2"; shift ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "usage: $0 [--keep] [--record-seconds S]" >&2; exit 2 ;;
  esac
  shift
done

log() { printf '\033[1m[container]\033[0m %s\n' "$*"; }
die() { printf '\033[1m[container]\033[0m ERROR: %s\n' "$*" >&2; exit 1; }
as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

# --- engine -----------------------------------------------------------------------------------
need=()
for p in podman runc debootstrap docker-compose; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
  log "installing ${need[*]}"
  as_root apt-get update -qq
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq "${need[@]}" >/dev/null
fi

# crun fails on this kernel's hybrid cgroups, and podman's default ulimits (nofile 1048576) are
# above the hard limits a container on these machines may set: runc, and limits no higher than
# the hard ones.
conf_dir=/etc/containers
nofile_hard=$(ulimit -Hn)
nproc_hard=$(ulimit -Hu)
[ "$nproc_hard" = unlimited ] || [ "$nproc_hard" -gt 32768 ] && nproc_hard=32768
[ "$nofile_hard" = unlimited ] && nofile_hard=1048576
conf="$conf_dir/containers.conf"
want=$(cat <<EOF
# written by lio-ppf scripts/container_check.sh
[containers]
default_ulimits = ["nofile=${nofile_hard}:${nofile_hard}", "nproc=${nproc_hard}:${nproc_hard}"]
[engine]
runtime = "runc"
EOF
)
if [ ! -f "$conf" ] || ! grep -q "lio-ppf scripts/container_check.sh" "$conf"; then
  [ -f "$conf" ] && as_root cp "$conf" "$conf.before-lio-ppf"
  log "writing $conf (runtime runc, ulimits nofile=$nofile_hard nproc=$nproc_hard)"
  echo "$want" | as_root tee "$conf" >/dev/null
fi
export PODMAN="podman"

# --- base image -------------------------------------------------------------------------------
if ! as_root podman image exists debian:12; then
  mirror=$(grep -h -o -m1 'http[s]*://[^ ]*debian/*$\|http[s]*://deb.debian.org/debian' \
             /etc/apt/sources.list.d/debian.sources /etc/apt/sources.list 2>/dev/null | head -1 || true)
  mirror=${mirror:-http://deb.debian.org/debian}
  rootfs=$(mktemp -d /tmp/ppf-rootfs.XXXXXX)
  log "making debian:12 with debootstrap from $mirror"
  as_root debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >/tmp/ppf-debootstrap.log 2>&1 ||
    die "debootstrap failed: see /tmp/ppf-debootstrap.log"
  as_root tar -C "$rootfs" -c . | as_root podman import --change 'CMD ["bash"]' - debian:12 >/dev/null
  as_root rm -rf "$rootfs"
fi

# --- build ------------------------------------------------------------------------------------
log "building docker/Dockerfile as lio-ppf:latest"
t0=$(date +%s)
as_root podman build --layers --build-arg PPF_BUILD_JOBS="${PPF_BUILD_JOBS:-}" \
  -f docker/Dockerfile -t lio-ppf:latest . >/tmp/ppf-image-build.log 2>&1 ||
  { tail -30 /tmp/ppf-image-build.log >&2; die "image build failed: /tmp/ppf-image-build.log"; }
build_s=$(( $(date +%s) - t0 ))
size_b=$(as_root podman image inspect lio-ppf:latest --format '{{.Size}}')
log "image built in ${build_s} s, size $(( size_b / 1000000 )) MB"

# The final image holds the install tree and runtime libraries only.
for leftover in /opt/lio-ppf/build /opt/lio-ppf/src /var/lib/apt/lists/deb.debian.org_debian_dists_bookworm_InRelease; do
  if as_root podman run --rm --entrypoint /bin/sh lio-ppf:latest -c "test -e $leftover"; then
    die "the image still contains $leftover"
  fi
done
as_root podman run --rm lio-ppf:latest ppf_node --help >/dev/null 2>&1 || die "ppf_node --help fails in the image"

# --- compose scenario -------------------------------------------------------------------------
sock=/tmp/ppf-podman-$$.sock
as_root podman system service --time=0 "unix://$sock" >/tmp/ppf-podman-service.log 2>&1 &
service_pid=$!
for _ in $(seq 50); do [ -S "$sock" ] && break; sleep 0.2; done
[ -S "$sock" ] || die "podman system service did not open $sock"
compose=(as_root env DOCKER_HOST="unix://$sock" docker-compose -p lio-ppf -f docker/compose.yaml)
cleanup() {
  if [ "$keep" -eq 0 ]; then "${compose[@]}" down -v >/dev/null 2>&1 || true; fi
  as_root kill "$service_pid" 2>/dev/null || true
  as_root rm -f "$sock"
}
trap cleanup EXIT
"${compose[@]}" config -q || die "docker-compose refuses docker/compose.yaml"
log "compose up (node + replay)"
"${compose[@]}" up -d --no-build >/tmp/ppf-compose.log 2>&1 || { cat /tmp/ppf-compose.log >&2; die "compose up failed"; }

rec_dir=$(mktemp -d /tmp/ppf-odom.XXXXXX)
log "recording /odometry for ${record_s} s from a third container"
as_root podman run --rm --network host --ipc host -v "$rec_dir:/rec" lio-ppf:latest \
  ppf_record --topics /odometry --out /rec/odom --duration "$record_s" >/tmp/ppf-record.log 2>&1 ||
  { cat /tmp/ppf-record.log >&2; die "ppf_record failed"; }
count=$(sed -n 's|.*PPF_RECORD_DONE /odometry=\([0-9]*\).*|\1|p' /tmp/ppf-record.log)
count=${count:-0}
# What was recorded must also read back from the bag.
as_root podman run --rm -v "$rec_dir:/rec" lio-ppf:latest ppf_bag_info /rec/odom | grep -E "Messages|/odometry"
for svc in node replay; do
  state=$(as_root podman ps -a --filter "name=lio-ppf_${svc}_1" --format '{{.Status}}' | head -1)
  log "service $svc: ${state:-not found}"
done
as_root podman logs lio-ppf_node_1 2>&1 | grep -E "IMU initialized|status=" | tail -2 || true

echo
echo "| build time | image size | odometry messages in ${record_s} s |"
echo "|---|---|---|"
echo "| ${build_s} s | $(( size_b / 1000000 )) MB | ${count} |"
[ "$count" -gt 0 ] || die "no odometry received from the node in the container"
