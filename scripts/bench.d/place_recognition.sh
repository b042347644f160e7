#!/usr/bin/env bash
# bench.d extension (issue 6): descriptor and database query time.
#   place_recognition.sh OUT_DIR DATA_DIR MAP_DIR BIN_DIR
# Runs place_recognition_benchmark: both descriptors (ring histogram, Scan Context) on the real
# VLP-16 scans of ../shared/data/real/vlp16_indoor, and queries against a synthetic database of
# 100,000 entries at three distances from the stored entries (0.02 and 0.065: revisits; 0.15:
# a place never seen, nothing within d_alpha). Writes OUT_DIR/bench.d/place_recognition.json
# with the medians and 95th percentiles in ms (and the benchmark's text output beside it).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../lib/common.sh"
out="$1" bin="$4"
[ -x "${bin}/place_recognition_benchmark" ] || msm_die "no ${bin}/place_recognition_benchmark"
scans="${MSM_REPO}/../shared/data/real/vlp16_indoor"
[ -d "${scans}" ] || msm_die "no real VLP-16 scans at ${scans}"
mkdir -p "${out}/bench.d"
text="${out}/bench.d/place_recognition.txt"
"${bin}/place_recognition_benchmark" "${scans}" 100000 | tee "${text}"
/usr/bin/python3 - "${text}" "${out}/bench.d/place_recognition.json" <<'PY'
import json, re, sys
text, path = sys.argv[1], sys.argv[2]
result = {'descriptor_ms': {}, 'query_ms': []}
for line in open(text):
    m = re.match(r'descriptor (\S+) .*median ([\d.]+) ms, p95 ([\d.]+) ms', line)
    if m:
        result['descriptor_ms'][m.group(1)] = {'median': float(m.group(2)), 'p95': float(m.group(3))}
    m = re.match(r'query (\S+)\s+noise ([\d.]+) entries (\d+) .*query median ([\d.]+) ms, '
                 r'p95 ([\d.]+) ms \((\d+)/(\d+) matched', line)
    if m:
        result['query_ms'].append({
            'descriptor': m.group(1), 'noise': float(m.group(2)), 'entries': int(m.group(3)),
            'median': float(m.group(4)), 'p95': float(m.group(5)),
            'matched': int(m.group(6)), 'queries': int(m.group(7))})
if not result['descriptor_ms'] or not result['query_ms']:
    sys.exit('place_recognition.sh: could not read the benchmark output %s' % text)
with open(path, 'w') as f:
    json.dump(result, f, indent=2)
    f.write('\n')
PY
