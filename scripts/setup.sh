#!/usr/bin/env bash
# Installs every system dependency of LIO-PPF from Debian 12 packages (idempotent) and builds the
# colcon workspace in Release. Downloads nothing but Debian and npm packages.
#
#   scripts/setup.sh              install what is missing, then build
#   scripts/setup.sh --deps-only  install only (used by docker/Dockerfile before copying sources)
#   scripts/setup.sh --no-deps    build only
#   scripts/setup.sh --runtime-packages
#                                 print the Debian packages whose shared libraries the built
#                                 install tree loads (docker/Dockerfile's runtime stage)
#   scripts/setup.sh --runtime-deps FILE
#                                 install only the packages FILE lists (one per line), then
#                                 drop apt's lists: the runtime image
#
# Environment: PPF_BUILD_JOBS (default: number of cores) bounds compile parallelism;
# PPF_BUILD_TESTING=OFF builds without the tests (the container image).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

# Kept in one place: docker/Dockerfile and test/test_docker_files.py check against this list.
# clang and its runtimes (libclang-rt-14-dev: ASan, UBSan, TSan, libFuzzer) serve the sanitizer
# and fuzzing stages of scripts/test.sh (scripts/sanitize.sh, scripts/fuzz.sh).
# python3-rosbag and python3-sensor-msgs (Debian's ROS 1 Python, for /usr/bin/python3) are the
# independent ROS 1 bag writer of ppf_bag's ROS 1 reader tests.
# python3-matplotlib (for /usr/bin/python3) draws the plots of scripts/ppf_report.py.
# docker-compose: its Compose Specification schema checks docker/compose.yaml in CI
# (test/system/test_docker_files.py; `docker compose` v2 is not packaged for Debian 12) and
# scripts/container_check.sh runs the compose file with it against podman.
PPF_DEBIAN_PACKAGES=(
  build-essential cmake pkg-config git ca-certificates
  colcon python3-colcon-cmake python3-colcon-package-selection python3-colcon-test-result
  python3-colcon-metadata python3-colcon-recursive-crawl python3-colcon-parallel-executor
  python3-colcon-bash python3-colcon-library-path python3-colcon-output python3-colcon-defaults
  python3-colcon-package-information python3-colcon-pkg-config python3-colcon-ros
  libfastrtps-dev libfastcdr-dev fastddsgen
  libeigen3-dev libpcl-dev libomp-dev libgtest-dev
  libyaml-cpp-dev libsqlite3-dev sqlite3 liblz4-dev libzstd-dev libbz2-dev
  cyclonedds-dev cyclonedds-tools
  python3-yaml nodejs npm
  python3-rosbag python3-sensor-msgs python3-matplotlib
  clang libclang-rt-14-dev
  docker-compose
)

deps=1
build=1
action=
case "${1:-}" in
  --deps-only) build=0 ;;
  --no-deps) deps=0 ;;
  --runtime-packages) action=runtime-packages ;;
  --runtime-deps)
    action=runtime-deps
    runtime_list="${2:-}"
    [ -f "$runtime_list" ] || { echo "$0: --runtime-deps needs a package list file" >&2; exit 2; }
    ;;
  "") ;;
  *) echo "usage: $0 [--deps-only|--no-deps|--runtime-packages|--runtime-deps FILE]" >&2; exit 2 ;;
esac

log() { printf '\033[1m[setup]\033[0m %s\n' "$*"; }

as_root() {
  if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

install_debian_packages() {
  local missing=()
  for p in "${PPF_DEBIAN_PACKAGES[@]}"; do
    # nodejs/npm: any node >= 18 already on PATH will do (the machine image may ship its own).
    if { [ "$p" = nodejs ] || [ "$p" = npm ]; } && command -v "${p/nodejs/node}" >/dev/null 2>&1; then
      continue
    fi
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    log "Debian packages: all ${#PPF_DEBIAN_PACKAGES[@]} present"
    return
  fi
  log "installing ${#missing[@]} Debian packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  as_root apt-get update -qq
  as_root apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

install_npm_test_tools() {
  # Independent MCAP reader/writer used by tests (@mcap/core, @foxglove/rosmsg2-serialization).
  [ -f test/js/package-lock.json ] || return 0
  if [ -d test/js/node_modules ] && [ test/js/node_modules/.package-lock.json -nt test/js/package-lock.json ]; then
    log "npm test tools: up to date"
    return
  fi
  log "installing npm test tools (test/js)"
  npm ci --prefix test/js --no-audit --no-fund --loglevel=error >/dev/null
}

build_workspace() {
  local jobs="${PPF_BUILD_JOBS:-$(nproc)}"
  log "building the workspace (Release, ${jobs} jobs)"
  # One package at a time with all cores each: PCL- and Eigen-heavy translation units need the
  # memory more than they need package-level parallelism. test/js (the Node interop tests'
  # scripts, npm-installed above) is the workspace's, not a package's: PPF_JS_DIR hands it to
  # ppf_bag and ppf_sim; the other packages ignore it, hence --no-warn-unused-cli.
  MAKEFLAGS="-j${jobs}" colcon build \
    --parallel-workers 1 \
    --event-handlers console_cohesion- console_stderr+ \
    --cmake-args -DCMAKE_BUILD_TYPE=Release -DPPF_JS_DIR="$ROOT/test/js" \
      -DBUILD_TESTING="${PPF_BUILD_TESTING:-ON}" --no-warn-unused-cli
  log "built: source install/setup.bash to use ppf_node, ppf_sim, ppf_offline, ppf_eval, ..."
}

list_runtime_packages() {
  # Every ELF file of the install tree through ldd; libraries outside install/ are mapped to
  # their Debian package. dpkg knows a file under the path it shipped it at, which on a
  # merged-/usr system may be the /lib or the /usr/lib spelling: both are tried.
  [ -d install ] || { echo "$0: no install/ tree: build first" >&2; exit 1; }
  local libs own
  own=$(readlink -f install)
  # ldd fails on the scripts among them (ppf_report: "not a dynamic executable"); through xargs
  # that was exit 123, which pipefail turned into a failed image build. One file at a time,
  # a script simply lists nothing.
  libs=$(find -L install -type f \( -perm -u+x -o -name '*.so*' \) -print0 |
           while IFS= read -r -d '' f; do ldd "$f" 2>/dev/null || true; done |
           awk '$2 == "=>" && $3 ~ /^\// {print $3}' | sort -u)
  local lib real pkg
  for lib in $libs; do
    real=$(readlink -f "$lib")
    case "$real" in "$own"/*) continue ;; esac
    pkg=""
    for candidate in "$lib" "$real" "${lib#/usr}" "/usr$lib" "${real#/usr}" "/usr$real"; do
      pkg=$(dpkg -S "$candidate" 2>/dev/null | head -1 | cut -d: -f1) && [ -n "$pkg" ] && break
    done
    [ -n "$pkg" ] || { echo "$0: no Debian package owns $lib" >&2; exit 1; }
    echo "$pkg"
  done | sort -u
}

install_runtime_packages() {
  local pkgs
  mapfile -t pkgs < <(grep -v '^\s*\(#\|$\)' "$runtime_list")
  log "installing ${#pkgs[@]} runtime packages: ${pkgs[*]}"
  export DEBIAN_FRONTEND=noninteractive
  as_root apt-get update -qq
  as_root apt-get install -y -qq --no-install-recommends "${pkgs[@]}" >/dev/null
  as_root apt-get clean
  as_root rm -rf /var/lib/apt/lists/*
}

case "$action" in
  runtime-packages) list_runtime_packages; exit 0 ;;
  runtime-deps) install_runtime_packages; exit 0 ;;
esac

if [ "$deps" -eq 1 ]; then
  install_debian_packages
  install_npm_test_tools
fi
if [ "$build" -eq 1 ]; then
  build_workspace
fi
