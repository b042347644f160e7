#!/usr/bin/env bash
# bench.d extension (issue 5): our odometry next to KISS-ICP (Vizzo et al., RA-L 2023), the
# peer a user would pick for LiDAR odometry, on the first session of DATA_DIR.
#   kiss_icp.sh OUT_DIR DATA_DIR MAP_DIR BIN_DIR
# KISS-ICP (PyPI kiss-icp, its default configuration, reading the bag itself) runs in the bench
# virtualenv build/bench_venv; our trajectory is the odometry of the same session in MAP_DIR
# (trajectories/<session>_odom.tum, written by bench.sh's offline_mapper run just before).
# Both are compared with the simulator's ground truth by scripts/lib/odometry_compare.py
# (evaluation only). ms/scan: KISS-ICP's own average, our deskew+odometry median, from the same
# bench run. Writes OUT_DIR/bench.d/kiss_icp.json and prints a Markdown table.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../lib/common.sh"
out="$(cd "$1" && pwd)" data="$(cd "$2" && pwd)" map="$(cd "$3" && pwd)"
[ -f "${data}/sessions.yaml" ] || msm_die "no simulated data at ${data}"
mapfile -t bags < <(msm_session_bags "${data}")
session="${bags[0]%.bag}"
ours="${map}/trajectories/${session}_odom.tum"
[ -f "${ours}" ] || msm_die "no odometry trajectory ${ours} (bench.sh maps the sessions first)"

venv="${MSM_REPO}/build/bench_venv"
if [ ! -x "${venv}/bin/kiss_icp_pipeline" ]; then
  msm_log "installing KISS-ICP into ${venv}"
  /usr/bin/python3 -m venv "${venv}" || msm_die "python3 -m venv failed (Debian: python3-venv)"
  "${venv}/bin/pip" install -q "kiss-icp==1.3.0" "rosbags==0.11.9" || msm_die "pip install kiss-icp failed"
fi

scratch="${out}/bench.d/kiss_icp"
rm -rf "${scratch}"
mkdir -p "${scratch}"
msm_log "KISS-ICP on ${bags[0]}"
(cd "${scratch}" && kiss_icp_out_dir="${scratch}/results" \
  "${venv}/bin/kiss_icp_pipeline" --topic /velodyne_points "${data}/${bags[0]}" \
  > "${scratch}/kiss_icp.log" 2>&1) || msm_die "kiss_icp_pipeline failed (see ${scratch}/kiss_icp.log)"
kiss="$(find "${scratch}/results" -name '*_poses_tum.txt' | head -n 1)"
[ -n "${kiss}" ] || msm_die "KISS-ICP wrote no TUM trajectory (see ${scratch}/kiss_icp.log)"
kiss_ms="$(sed -n 's/.*Average Runtime *| *\([0-9.]*\).*/\1/p' "$(dirname "${kiss}")/result_metrics.log" | head -n 1)"
our_ms="$(/usr/bin/python3 -c "import yaml,sys; print(yaml.safe_load(open(sys.argv[1]))['per_scan_ms']['deskew_odometry']['median'])" "${map}/timing/${session}.yaml" 2>/dev/null || true)"
/usr/bin/python3 "${MSM_REPO}/scripts/lib/odometry_compare.py" --truth "${data}/truth/${session}.tum" \
  --json "${out}/bench.d/kiss_icp.json" \
  "kiss_icp=${kiss}${kiss_ms:+:${kiss_ms}}" "multisession_mapper=${ours}${our_ms:+:${our_ms}}" \
  | tee "${scratch}/comparison.md"
