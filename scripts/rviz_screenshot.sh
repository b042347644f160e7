#!/usr/bin/env bash
# Screenshot of RViz (rviz/mapping.rviz) showing a stored map directory: starts Xvfb and a
# private roscore, publishes the map's cloud, submaps, loop candidates (loops/<session>.csv)
# and removed/mended dynamic points (dynamics/) with scripts/rviz_publish_map.py, and writes a
# PNG of the screen. The view is centred on the map's trajectories.
#   scripts/rviz_screenshot.sh --map DIR [--out PNG] [--wait SECONDS] [--small]
#   (--small: 64-colour PNG, about 250 KB, for docs/images)
#   scripts/rviz_screenshot.sh --synthetic [--out PNG]
# Needs a built workspace (scripts/build.sh; MSM_WS selects it).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

map=""
synthetic=0
out="${MSM_REPO}/demo_output/rviz_mapping.png"
wait_s=20
small=0
while [ $# -gt 0 ]; do
  case "$1" in
    --map) map="$2"; shift 2 ;;
    --synthetic) synthetic=1; shift ;;
    --out) out="$2"; shift 2 ;;
    --wait) wait_s="$2"; shift 2 ;;
    --small) small=1; shift ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) msm_die "unknown argument '$1' (see --help)" ;;
  esac
done
if [ ${synthetic} -eq 0 ]; then
  [ -n "${map}" ] || msm_die "give --map DIR or --synthetic"
  [ -f "${map}/manifest.yaml" ] || msm_die "${map} has no manifest.yaml"
  map="$(cd "${map}" && pwd)"
fi
for tool in Xvfb rviz import roscore; do
  command -v "${tool}" >/dev/null || msm_die "${tool} is not installed (scripts/build.sh installs it)"
done
[ -f "${MSM_WS}/devel/setup.bash" ] || msm_die "no workspace in ${MSM_WS}: run scripts/build.sh first"
mkdir -p "$(dirname "${out}")"
out="$(cd "$(dirname "${out}")" && pwd)/$(basename "${out}")"

tmp="$(mktemp -d -t msm_rviz_XXXXXX)"
pids=()
cleanup() {
  # Newest first, each given 5 s to exit: RViz must be gone before its X server.
  local i pid
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do
    pid="${pids[i]}"
    kill -INT "${pid}" 2>/dev/null || continue
    for _ in $(seq 50); do kill -0 "${pid}" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "${pid}" 2>/dev/null || true
  done
  # The logs of RViz and the publisher, beside the screenshot.
  for log in rviz publisher; do
    [ -f "${tmp}/${log}.log" ] && { echo "==== ${log}"; cat "${tmp}/${log}.log"; }
  done >"${out%.png}.log" 2>/dev/null || true
  rm -rf "${tmp}"
}
trap cleanup EXIT

# Private ROS environment: own ROS_HOME, free master port, the workspace's packages.
export ROS_HOME="${tmp}/ros_home"
msm_source_workspace
port="$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
export ROS_MASTER_URI="http://localhost:${port}"

# The view: centred on the trajectories, far enough to see all of them.
config="${tmp}/mapping.rviz"
/usr/bin/python3 - "${MSM_REPO}/rviz/mapping.rviz" "${config}" "${map}" <<'EOF'
import os, sys, yaml
source, target, map_dir = sys.argv[1:4]
config = yaml.safe_load(open(source))
if map_dir:
    # Extent of the trajectories (the submap origins when there is none).
    points = [s['origin'][:3] for s in yaml.safe_load(open(map_dir + '/manifest.yaml'))['submaps']]
    folder = map_dir + '/trajectories'
    for name in os.listdir(folder) if os.path.isdir(folder) else []:
        if name.endswith('.tum') and not name.endswith('_odom.tum'):
            for line in open(os.path.join(folder, name)):
                values = line.split()
                if len(values) == 8 and not line.startswith('#'):
                    points.append([float(v) for v in values[1:4]])
    lo = [min(o[i] for o in points) for i in range(3)]
    hi = [max(o[i] for o in points) for i in range(3)]
    view = config['Visualization Manager']['Views']['Current']
    view['Focal Point'] = {'X': (lo[0] + hi[0]) / 2, 'Y': (lo[1] + hi[1]) / 2, 'Z': lo[2]}
    extent = max(hi[0] - lo[0], hi[1] - lo[1])
    view['Distance'] = max(40.0, 1.5 * extent)
    view['Pitch'] = 1.2
    # Hundreds of loops: labels and rejected loops would hide the map and the accepted loops.
    num_loops = 0
    for session in os.listdir(map_dir + '/loops') if os.path.isdir(map_dir + '/loops') else []:
        num_loops += max(0, sum(1 for _ in open(map_dir + '/loops/' + session)) - 1)
    for display in config['Visualization Manager']['Displays']:
        if display.get('Class') == 'multisession_mapper/LoopCandidates':
            display['Line Width'] = max(0.1, extent / 500.0)
            display['Undefined Marker Size'] = max(1.0, extent / 100.0)
            if num_loops > 100:
                display['Show Text'] = False
                display['Show Rejected'] = False
                print('%d loops: rejected loops and labels hidden' % num_loops, file=sys.stderr)
yaml.safe_dump(config, open(target, 'w'), default_flow_style=False, sort_keys=False)
EOF

read_fd_file="${tmp}/display"
Xvfb -displayfd 1 -screen 0 1280x800x24 +extension GLX +render -noreset -nolisten tcp \
  >"${read_fd_file}" 2>"${tmp}/xvfb.log" &
pids+=($!)
for _ in $(seq 50); do [ -s "${read_fd_file}" ] && break; sleep 0.1; done
[ -s "${read_fd_file}" ] || msm_die "Xvfb did not start (see ${tmp}/xvfb.log)"
export DISPLAY=":$(head -n 1 "${read_fd_file}")"

roscore -p "${port}" >"${tmp}/roscore.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do rostopic list >/dev/null 2>&1 && break; sleep 0.2; done
rostopic list >/dev/null 2>&1 || msm_die "roscore did not start"

msm_log "RViz on ${DISPLAY} with ${config}"
rviz -d "${config}" >"${tmp}/rviz.log" 2>&1 &
pids+=($!)
if [ ${synthetic} -eq 1 ]; then
  source_args=(--synthetic)
else
  source_args=(--map "${map}" --voxel 0.5)
fi
/usr/bin/python3 "${MSM_REPO}/scripts/rviz_publish_map.py" "${source_args[@]}" \
  >"${tmp}/publisher.log" 2>&1 &
pids+=($!)
sleep "${wait_s}"
grep -E "PluginlibFactory|Failed to load" "${tmp}/rviz.log" >&2 && msm_die "rviz could not load a plugin"
grep -h "published" "${tmp}/publisher.log" >&2 || msm_log "warning: the publisher has not published yet"
import -window root "${out}"
if [ ${small} -eq 1 ]; then
  convert "${out}" -colors 64 -define png:compression-level=9 "${out}.tmp.png" && mv "${out}.tmp.png" "${out}"
fi
msm_log "screenshot: ${out} ($(du -k "${out}" | cut -f1) KB)"
