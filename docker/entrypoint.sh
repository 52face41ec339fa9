#!/usr/bin/env bash
# Puts every package of the colcon install on PATH/LD_LIBRARY_PATH, then runs the given command
# (default: ppf_node). Globbing instead of sourcing install/setup.bash: colcon's setup scripts
# need python3, which the runtime image does not carry.
set -e
for prefix in /opt/lio-ppf/install/*/; do
  [ -d "${prefix}bin" ] && PATH="${prefix}bin:$PATH"
  [ -d "${prefix}lib" ] && LD_LIBRARY_PATH="${prefix}lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
done
export PATH LD_LIBRARY_PATH
exec "$@"
