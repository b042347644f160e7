#!/usr/bin/env bash
# Installs the Debian packages the package needs (apt-get; sudo only when not root) and builds
# it in the ignored workspace build/ws (MSM_WS overrides). Extra arguments go to catkin_make.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"
msm_install_deps
msm_build "$@"
msm_log "built: source ${MSM_WS}/devel/setup.bash to use rosrun/roslaunch"
