#!/usr/bin/env bash
# bench.d extension (issue 6): inter-session loop detection without initial guess.
#   global_registration.sh OUT_DIR DATA_DIR MAP_DIR BIN_DIR
# Maps the first session of DATA_DIR alone into a scratch map, then runs inter_session_benchmark
# for every further session against it with both global registration methods (FPFH + RANSAC,
# yaw search + multi-start ICP). The benchmark reads the simulator truth for evaluation only.
# Writes OUT_DIR/bench.d/global_registration.json: {"<session>": {per-method figures}}.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../lib/common.sh"
out="$1" data="$2" bin="$4"
[ -x "${bin}/inter_session_benchmark" ] || msm_die "no ${bin}/inter_session_benchmark"
[ -f "${data}/sessions.yaml" ] || msm_die "no simulated data at ${data}"
scratch="${out}/bench.d/global_registration"
rm -rf "${scratch}"
mkdir -p "${scratch}"
mapfile -t bags < <(msm_session_bags "${data}")
[ ${#bags[@]} -ge 2 ] || msm_die "need at least two sessions"
"${bin}/offline_mapper" --bag "${data}/${bags[0]}" --map "${scratch}/map" --quiet
parts=()
for bag in "${bags[@]:1}"; do
  name="${bag%.bag}"
  "${bin}/inter_session_benchmark" --map "${scratch}/map" --bag "${data}/${bag}" \
    --truth-dir "${data}/truth" --method both --json "${scratch}/${name}.json" \
    | tee "${scratch}/${name}.txt"
  parts+=("${scratch}/${name}.json")
done
/usr/bin/python3 - "${out}/bench.d/global_registration.json" "${parts[@]}" <<'PY'
import json, sys
merged = {}
for path in sys.argv[2:]:
    with open(path) as f:
        d = json.load(f)
    merged[d['session']] = d
with open(sys.argv[1], 'w') as f:
    json.dump(merged, f, indent=1)
PY
rm -rf "${scratch}/map"
