#!/usr/bin/env bash
# bench.d extension (issue 6): inter-session loop detection without initial guess.
#   global_registration.sh OUT_DIR DATA_DIR MAP_DIR BIN_DIR
# Maps the first session of DATA_DIR alone into a scratch map, then runs inter_session_benchmark
# for every further session against it with both global registration methods (FPFH + RANSAC,
# yaw search + multi-start ICP). The benchmark reads the simulator truth for evaluation only.
# Then times our FPFH against PCL's FPFHEstimation on the scratch map's submaps
# (global_registration_benchmark --compare-fpfh, same run).
# Writes OUT_DIR/bench.d/global_registration.json: {"<session>": {per-method figures},
# "fpfh": {"pcl_ms": .., "own_ms": .., "speedup": .., "same_percent": .., "line": ..}}.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../lib/common.sh"
out="$1" data="$2" bin="$4"
[ -x "${bin}/inter_session_benchmark" ] || msm_die "no ${bin}/inter_session_benchmark"
[ -x "${bin}/global_registration_benchmark" ] || msm_die "no ${bin}/global_registration_benchmark"
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
"${bin}/global_registration_benchmark" --map "${scratch}/map" --compare-fpfh --max-pairs 20 \
  | tee "${scratch}/fpfh.txt"
/usr/bin/python3 - "${out}/bench.d/global_registration.json" "${scratch}/fpfh.txt" \
  "${parts[@]}" <<'PY'
import json, re, sys
merged = {}
for path in sys.argv[3:]:
    with open(path) as f:
        d = json.load(f)
    merged[d['session']] = d
line = open(sys.argv[2]).read().strip()
m = re.search(r'PCL FPFHEstimation ([0-9.]+) ms .*ours ([0-9.]+) ms \(([0-9.]+)x faster\)'
              r'.* ([0-9.]+) % within', line)
if not m:
    sys.exit('global_registration.sh: cannot read the FPFH comparison: ' + line)
merged['fpfh'] = {'pcl_ms': float(m.group(1)), 'own_ms': float(m.group(2)),
                  'speedup': float(m.group(3)), 'same_percent': float(m.group(4)), 'line': line}
with open(sys.argv[1], 'w') as f:
    json.dump(merged, f, indent=1)
PY
rm -rf "${scratch}/map"
