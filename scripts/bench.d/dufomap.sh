#!/usr/bin/env bash
# bench.d extension (issue 7): our static map next to DUFOMap (Duberg et al., RA-L 2024), the
# DynamicMap benchmark's leading dynamic-point remover, on all sessions of DATA_DIR.
#   dufomap.sh OUT_DIR DATA_DIR MAP_DIR BIN_DIR
# DUFOMap (PyPI dufomap, resolution 0.1 m, d_s 0.2 m, d_p 1: the paper's defaults) runs in the
# bench virtualenv build/bench_venv on every scan of every session, placed (and deskewed) with
# the simulator's truth poses; its static output cloud and our map MAP_DIR (own SLAM poses,
# written by bench.sh's offline_mapper runs) are scored in the same run by the evaluator's
# dynamics code (scripts/lib/dufomap_compare.py; evaluation only). BIN_DIR is not used.
# MSM_DUFOMAP_THREADS sets DUFOMap's thread count (default 0: its own choice).
# Writes OUT_DIR/bench.d/dufomap.json and prints a Markdown table.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../lib/common.sh"
out="$(cd "$1" && pwd)" data="$(cd "$2" && pwd)" map="$(cd "$3" && pwd)"
[ -f "${data}/sessions.yaml" ] || msm_die "no simulated data at ${data}"
[ -f "${map}/manifest.yaml" ] || msm_die "no map at ${map} (bench.sh maps the sessions first)"
# DUFOMap keeps every input point in memory (small x3: 30 M points, 2.6 GB peak); the campus
# profile has about ten times as many. Above MSM_DUFOMAP_MAX_BAG_MB of bags (default 1500) the
# comparison is skipped unless MSM_DUFOMAP_FORCE=1.
bag_mb="$(du -cm "${data}"/*.bag | tail -n 1 | cut -f1)"
if [ "${bag_mb}" -gt "${MSM_DUFOMAP_MAX_BAG_MB:-1500}" ] && [ "${MSM_DUFOMAP_FORCE:-0}" != 1 ]; then
  msm_log "DUFOMap skipped: ${bag_mb} MB of bags would not fit in memory (run bench.sh --profile small, or set MSM_DUFOMAP_FORCE=1)"
  printf '{"skipped": "%s MB of bags; limit MSM_DUFOMAP_MAX_BAG_MB=%s"}\n' "${bag_mb}" \
    "${MSM_DUFOMAP_MAX_BAG_MB:-1500}" > "${out}/bench.d/dufomap.json"
  exit 0
fi

venv="${MSM_REPO}/build/bench_venv"
[ -x "${venv}/bin/python" ] || /usr/bin/python3 -m venv "${venv}" \
  || msm_die "python3 -m venv failed (Debian: python3-venv)"
# Pinned: dufomap 1.1.1 (DUFOMap), rosbags 0.11.9 (bag reading, as kiss_icp.sh); PyYAML and
# scipy for the evaluator (scipy's k-d tree only makes the scoring faster).
if ! "${venv}/bin/python" -c "import dufomap, rosbags, yaml, scipy" 2>/dev/null; then
  msm_log "installing DUFOMap into ${venv}"
  "${venv}/bin/pip" install -q "dufomap==1.1.1" "rosbags==0.11.9" "PyYAML==6.0.3" \
    "scipy==1.17.1" || msm_die "pip install dufomap failed"
fi

scratch="${out}/bench.d/dufomap"
rm -rf "${scratch}"
mkdir -p "${scratch}"
msm_log "DUFOMap on the sessions of ${data}"
"${venv}/bin/python" "${MSM_REPO}/scripts/lib/dufomap_compare.py" --data "${data}" \
  --map "${map}" --scratch "${scratch}" --json "${out}/bench.d/dufomap.json" \
  --threads "${MSM_DUFOMAP_THREADS:-0}" 2> "${scratch}/dufomap.log" \
  | tee "${scratch}/comparison.md" \
  || msm_die "dufomap_compare.py failed (see ${scratch}/dufomap.log)"
# The static cloud is a large file (every static input point): keep only the table and JSON.
rm -f "${scratch}/dufomap_output.pcd"
