# Shared by scripts/build.sh, test.sh, demo.sh and bench.sh: install, workspace, environment.
# Sourced, not run.

# Debian's python first: a pyenv python3 on PATH lacks the ROS modules (ros-on-debian quirk 1).
export PATH="/usr/bin:/bin:${PATH}"
export ROS_HOSTNAME="${ROS_HOSTNAME:-localhost}"    # quirk 5

MSM_REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
MSM_WS="${MSM_WS:-build/ws}"
case "${MSM_WS}" in /*) ;; *) MSM_WS="${MSM_REPO}/${MSM_WS}" ;; esac
export MSM_REPO MSM_WS

msm_log() { printf '\033[1m[%s] %s\033[0m\n' "$(date +%H:%M:%S)" "$*" >&2; }
msm_die() { printf '\033[31merror: %s\033[0m\n' "$*" >&2; exit 1; }

# Debian packages the build, tests and demo need (see ../shared/ros-on-debian.md).
MSM_APT_PACKAGES=(
  build-essential cmake catkin ros-core-dev libroscpp-dev rosbash
  libnodeletlib-dev libnodeletlib-tools
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  libpcl-dev libpcl-ros-dev libpcl-conversions-dev
  libtf2-ros-dev libtf2-eigen-dev libnav-msgs-dev
  librosbag-dev python3-rosbag python3-sensor-msgs
  librviz-dev rviz
  liboctomap-dev libceres-dev libnanoflann-dev libyaml-cpp-dev
  python3-rostest libgtest-dev python3-pytest
  python3-numpy python3-matplotlib python3-yaml python3-scipy pcl-tools
  xvfb imagemagick python3-nav-msgs   # the last one: scripts/rviz_publish_map.py (Path)
  # reliability (issue 9): libFuzzer + sanitizers of scripts/fuzz.sh (clang's runtime libraries)
  clang libclang-rt-14-dev
  python3-venv                # scripts/bench.d/kiss_icp.sh: the bench virtualenv (KISS-ICP)
)

msm_install_deps() {
  local missing=()
  for pkg in "${MSM_APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "${pkg}" 2>/dev/null | grep -q "install ok installed" \
      || missing+=("${pkg}")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    return 0
  fi
  msm_log "installing ${#missing[@]} Debian packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || msm_die "not root and no sudo: install as root: ${missing[*]}"
    sudo="sudo"
  fi
  ${sudo} env DEBIAN_FRONTEND=noninteractive apt-get update -q \
    || msm_die "apt-get update failed"
  ${sudo} env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
    "${missing[@]}" || msm_die "apt-get install failed"
  # rospack caches its crawl (quirk 4).
  rospack profile >/dev/null 2>&1 || true
}

# Creates the catkin workspace (ignored folder) with the repository linked into its source
# space MSM_SRC. The link back to the repository must not be reachable from inside it: rosrun
# looks for an executable with `find -L` over the whole package folder, and roslaunch / rostest
# walk it following links, so a link from build/ back to the repository made rosrun print
# "File system loop detected" on every call (and makes a walk that does not skip hidden
# folders endless). A workspace inside the repository (the default build/ws) therefore gets its
# source space outside it, in the user's cache folder, one per repository path; a workspace
# elsewhere (MSM_WS=/some/ws) keeps it at ${MSM_WS}/src. Workspaces created before with
# ${MSM_WS}/.src are moved over (their build folder is made anew once: CMake keeps the source
# path). Pass MSM_SRC to every catkin_make: --source "${MSM_SRC}".
msm_prepare_workspace() {
  case "${MSM_WS}/" in
    "${MSM_REPO}/"*)
      local key
      key="$(printf '%s' "${MSM_REPO}" | md5sum | cut -c1-12)"
      MSM_SRC="${XDG_CACHE_HOME:-${HOME:-/tmp}/.cache}/multisession_mapper/src-${key}"
      # The repository must not be walked into by rospack / catkin from its own build/.
      mkdir -p "${MSM_REPO}/build"
      touch "${MSM_REPO}/build/CATKIN_IGNORE"
      ;;
    *) MSM_SRC="${MSM_WS}/src" ;;
  esac
  export MSM_SRC
  # catkin_make -C needs the workspace folder to exist (a fresh clone has no build/ws yet).
  mkdir -p "${MSM_WS}"
  local cache="${MSM_WS}/build/CMakeCache.txt"
  if [ -f "${cache}" ] && ! grep -qxF "CMAKE_HOME_DIRECTORY:INTERNAL=${MSM_SRC}" "${cache}"; then
    msm_log "the workspace ${MSM_WS} was configured with another source space: building it anew"
    rm -rf "${MSM_WS}/build" "${MSM_WS}/devel"
  fi
  rm -rf "${MSM_WS}/.src"  # the old source space inside the repository (the loop)
  mkdir -p "${MSM_SRC}"
  if [ ! -e "${MSM_SRC}/multisession_mapper" ]; then
    ln -s "${MSM_REPO}" "${MSM_SRC}/multisession_mapper"
  fi
}

msm_build() {
  msm_prepare_workspace
  local first_build=0
  [ -f "${MSM_WS}/devel/setup.bash" ] || first_build=1
  local jobs="${MSM_JOBS:-$(nproc)}"
  local args=(-C "${MSM_WS}" --source "${MSM_SRC}" -DPYTHON_EXECUTABLE=/usr/bin/python3 -j"${jobs}")
  # Release by default; a user's CMAKE_BUILD_TYPE / flags win.
  if [ -n "${CMAKE_BUILD_TYPE:-}" ]; then
    args+=(-DCMAKE_BUILD_TYPE="${CMAKE_BUILD_TYPE}")
  elif [ ${first_build} -eq 1 ]; then
    args+=(-DCMAKE_BUILD_TYPE=Release)
  fi
  msm_log "building in ${MSM_WS} (${jobs} jobs)"
  catkin_make "${args[@]}" "$@" || msm_die "build failed"
  if [ ${first_build} -eq 1 ]; then
    # The package's own python path exists only after the first build (quirk 2).
    # shellcheck disable=SC1091
    (set +u; source "${MSM_WS}/devel/setup.bash"; catkin_make -C "${MSM_WS}" --source "${MSM_SRC}" --force-cmake \
       -DPYTHON_EXECUTABLE=/usr/bin/python3 -j"${jobs}" "$@") || msm_die "re-configure failed"
  fi
}

msm_source_workspace() {
  # shellcheck disable=SC1091
  set +u; source "${MSM_WS}/devel/setup.bash"; set -u
  export ROS_HOME="${ROS_HOME:-${MSM_WS}/ros_home}"
  mkdir -p "${ROS_HOME}"
}

# Bag file names of a simulator output folder, in recording order (from its sessions.yaml).
msm_session_bags() {
  /usr/bin/python3 -c "import yaml,sys; [print(s['bag']) for s in yaml.safe_load(open(sys.argv[1]))['sessions']]" "$1/sessions.yaml"
}
