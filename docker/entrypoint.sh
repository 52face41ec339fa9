#!/usr/bin/env bash
# Puts the colcon install on PATH/LD_LIBRARY_PATH, then runs the given command (default: ppf_node).
set -e
set +u
# shellcheck disable=SC1091
source /opt/lio-ppf/install/setup.bash
exec "$@"
