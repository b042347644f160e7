#!/usr/bin/env bash
# bench.d extension (issue 7): low-dynamic detection between overlapping submaps of two sessions.
#   dynamics.sh OUT_DIR DATA_DIR MAP_DIR BIN_DIR
# Maps the first two sessions of DATA_DIR separately (offline_mapper, one scratch map each), then
# runs dynamic_detection_benchmark on them: submaps placed by the truth poses (evaluation only),
# pairs within 15 m, low-dynamic DA, static and canopy SA with the height guard on and off, and
# the time per pair. Writes OUT_DIR/bench.d/dynamics.json.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../lib/common.sh"
out="$1" data="$2" bin="$4"
[ -x "${bin}/dynamic_detection_benchmark" ] || msm_die "no ${bin}/dynamic_detection_benchmark"
[ -f "${data}/sessions.yaml" ] || msm_die "no simulated data at ${data}"
scratch="${out}/bench.d/dynamics"
rm -rf "${scratch}"
mkdir -p "${scratch}"
mapfile -t bags < <(msm_session_bags "${data}")
[ ${#bags[@]} -ge 2 ] || msm_die "need at least two sessions"
for bag in "${bags[@]:0:2}"; do
  "${bin}/offline_mapper" --bag "${data}/${bag}" --map "${scratch}/map_${bag%.bag}" --quiet
done
"${bin}/dynamic_detection_benchmark" --sim "${data}" \
  --history-map "${scratch}/map_${bags[0]%.bag}" --current-map "${scratch}/map_${bags[1]%.bag}" \
  --history "${bags[0]%.bag}" --current "${bags[1]%.bag}" \
  --json "${out}/bench.d/dynamics.json" | tee "${scratch}/dynamics.txt"
rm -rf "${scratch}"/map_*
