#!/usr/bin/env bash
# The main job on the embedded data: installs what is missing, builds, generates the simulated
# multi-session campus (cached), maps every session into one map, evaluates it against the
# simulator's ground truth and prints the paper-style tables.
#   scripts/demo.sh [--profile small|campus] [--sessions N] [--seed S] [--out DIR]
#                   [--rviz-screenshot]   (also: RViz under Xvfb showing the map, OUT/rviz_mapping.png)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

profile=small
rviz_screenshot=0
sessions=3
seed=1
out="${MSM_REPO}/demo_output"
while [ $# -gt 0 ]; do
  case "$1" in
    --profile) profile="$2"; shift 2 ;;
    --sessions) sessions="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --rviz-screenshot) rviz_screenshot=1; shift ;;
    -h|--help) sed -n '2,7p' "$0"; exit 0 ;;
    *) msm_die "unknown argument '$1' (see --help)" ;;
  esac
done
case "${profile}" in small|campus) ;; *) msm_die "--profile must be small or campus" ;; esac

msm_install_deps
msm_build
msm_source_workspace
bin="${MSM_WS}/devel/lib/multisession_mapper"
data="${out}/data_${profile}_${sessions}s_seed${seed}"
map="${out}/map_${profile}"
report="${out}/report_${profile}"
missing=()

# 1. Embedded data: the simulated campus (generated once, then reused).
if [ -x "${bin}/simulate_campus" ]; then
  if [ -f "${data}/sessions.yaml" ]; then
    msm_log "simulated campus: reusing ${data}"
  else
    msm_log "simulating the ${profile} campus: ${sessions} sessions, seed ${seed}"
    rm -rf "${data}.partial"
    "${bin}/simulate_campus" --profile "${profile}" --sessions "${sessions}" --seed "${seed}" \
      --out "${data}.partial"
    mv "${data}.partial" "${data}"
  fi
else
  missing+=("simulate_campus (the simulator, issue 3) is not built yet: no data to map")
fi

# 2. The multi-session pipeline: every session merged into one map, in recording order.
if [ -x "${bin}/offline_mapper" ] && [ -f "${data}/sessions.yaml" ]; then
  rm -rf "${map}"
  for bag in $(msm_session_bags "${data}"); do
    msm_log "mapping ${bag}"
    set +e
    "${bin}/offline_mapper" --bag "${data}/${bag}" --map "${map}"
    code=$?
    set -e
    if [ ${code} -eq 3 ]; then
      missing+=("${bag} could not be merged into the map (message above); the map keeps the other sessions")
      continue
    fi
    [ ${code} -eq 0 ] || msm_die "offline_mapper failed on ${bag}"
  done
else
  missing+=("offline_mapper (the mapping pipeline, issues 5-7) is not built yet: no map")
fi

# 3. Evaluation against ground truth, with the paper's tables.
if [ -d "${map}" ] && [ -f "${MSM_REPO}/python/multisession_mapper_eval/cli.py" ]; then
  msm_log "evaluating ${map}"
  "${MSM_REPO}/scripts/evaluate" --map "${map}" --truth "${data}" --out "${report}"
else
  missing+=("evaluation skipped: it needs a map from step 2")
fi

# 4. Optional: RViz (rviz/mapping.rviz) showing the map, its loops and removed points.
if [ ${rviz_screenshot} -eq 1 ]; then
  if [ -f "${map}/manifest.yaml" ]; then
    "${MSM_REPO}/scripts/rviz_screenshot.sh" --map "${map}" --out "${out}/rviz_mapping.png" \
      || missing+=("the RViz screenshot failed (log: ${out}/rviz_mapping.log)")
  else
    missing+=("RViz screenshot skipped: it needs a map from step 2")
  fi
fi

echo
echo "outputs:"
[ -d "${data}" ] && echo "  simulated sessions and ground truth: ${data}"
[ -d "${map}" ] && echo "  map directory:                        ${map}"
[ -d "${report}" ] && echo "  evaluation report (md, json, png):    ${report}"
[ -f "${out}/rviz_mapping.png" ] && echo "  RViz screenshot:                      ${out}/rviz_mapping.png"
if [ ${#missing[@]} -gt 0 ]; then
  echo
  echo "not available yet in this version:"
  for m in "${missing[@]}"; do echo "  - ${m}"; done
fi
