#!/usr/bin/env bash
# The benchmark of issue 4: generates the benchmark data once (simulator, fixed seed), maps the
# sessions one after the other into one map with the offline runner, evaluates the map against
# the simulator's ground truth and writes bench.json (timings and headline metrics).
# It measures; it asserts nothing about speed, and CI does not run it.
#   scripts/bench.sh [--profile campus|small] [--sessions N] [--seed S] [--out DIR] [--no-build]
# Steps whose tool does not exist yet are reported as not available (in bench.json too).
# Extension point: every executable scripts/bench.d/*.sh is run as
#   <script> OUT_DIR DATA_DIR MAP_DIR BIN_DIR
# and may write OUT_DIR/bench.d/<name>.json, merged into bench.json under "extra".<name>
# (for the comparisons with KISS-ICP, Scan Context, DUFOMap of issues 5-7).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

profile=campus
sessions=3
seed=1
out="${MSM_REPO}/bench_output"
build=1
while [ $# -gt 0 ]; do
  case "$1" in
    --profile) profile="$2"; shift 2 ;;
    --sessions) sessions="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --no-build) build=0; shift ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    *) msm_die "unknown argument '$1' (see --help)" ;;
  esac
done
case "${profile}" in small|campus) ;; *) msm_die "--profile must be small or campus" ;; esac
case "${sessions}" in ''|*[!0-9]*) msm_die "--sessions must be a positive integer" ;; esac

mkdir -p "${out}"
out="$(cd "${out}" && pwd)"
if [ ${build} -eq 1 ]; then
  msm_install_deps
  msm_build
fi
if [ -f "${MSM_WS}/devel/setup.bash" ]; then
  msm_source_workspace
fi
bin="${MSM_WS}/devel/lib/multisession_mapper"
data="${out}/data_${profile}_${sessions}s_seed${seed}"
map="${out}/map_${profile}_${sessions}s_seed${seed}"
report="${out}/report_${profile}_${sessions}s_seed${seed}"
steps="${out}/steps"     # one JSON per measured step, merged into bench.json at the end
rm -rf "${steps}" "${out}/bench.d"
mkdir -p "${steps}" "${out}/bench.d"

# run_timed NAME CMD...: runs CMD, records wall time, peak RSS of the process tree's largest
# process and the exit status in ${steps}/NAME.json; returns CMD's status.
run_timed() {
  local name="$1"
  shift
  /usr/bin/python3 - "${steps}/${name}.json" "$@" <<'PY'
import json, resource, subprocess, sys, time
path, cmd = sys.argv[1], sys.argv[2:]
start = time.monotonic()
status = subprocess.call(cmd)
wall = time.monotonic() - start
rss_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
with open(path, 'w') as f:
    json.dump({'command': cmd, 'wall_s': wall, 'peak_rss_mb': rss_kb / 1024.0,
               'exit_status': status}, f, indent=1)
sys.exit(status)
PY
}

not_available() {  # NAME REASON
  msm_log "NOT AVAILABLE: $2"
  printf '{"available": false, "reason": "%s"}\n' "$2" > "${steps}/$1.json"
}

# 1. Benchmark data (generated once per profile/sessions/seed, then reused).
if [ -f "${data}/sessions.yaml" ]; then
  msm_log "benchmark data: reusing ${data}"
  printf '{"available": true, "reused": true}\n' > "${steps}/simulate.json"
elif [ -x "${bin}/simulate_campus" ]; then
  msm_log "simulating the ${profile} campus: ${sessions} sessions, seed ${seed}"
  rm -rf "${data}.partial"
  if run_timed simulate "${bin}/simulate_campus" --profile "${profile}" \
       --sessions "${sessions}" --seed "${seed}" --out "${data}.partial"; then
    mv "${data}.partial" "${data}"
  else
    msm_log "simulate_campus failed (see above)"
  fi
else
  not_available simulate "simulate_campus (issue 3) is not built yet in ${bin}"
fi

# 2. The pipeline: every session merged into one map, in recording order, each one timed.
if [ -x "${bin}/offline_mapper" ] && [ -f "${data}/sessions.yaml" ]; then
  rm -rf "${map}"
  index=0
  for bag in $(msm_session_bags "${data}"); do
    msm_log "mapping ${bag} into ${map}"
    run_timed "$(printf 'map_%02d' ${index})" "${bin}/offline_mapper" --bag "${data}/${bag}" \
      --map "${map}" || msm_log "offline_mapper failed on ${bag} (see above)"
    index=$((index + 1))
  done
elif [ ! -x "${bin}/offline_mapper" ]; then
  not_available map_00 "offline_mapper (issues 5-7) is not built yet in ${bin}"
else
  not_available map_00 "no benchmark data to map (step 1 not available)"
fi

# 3. Evaluation against ground truth.
if [ -f "${map}/manifest.yaml" ]; then
  msm_log "evaluating ${map}"
  run_timed evaluate "${MSM_REPO}/scripts/evaluate" --map "${map}" --truth "${data}" \
    --out "${report}" || msm_log "evaluate failed (see above)"
else
  not_available evaluate "no map directory to evaluate (step 2 not available)"
fi

# 4. Contributed comparisons (scripts/bench.d/*.sh), if any.
if [ -d "${MSM_REPO}/scripts/bench.d" ]; then
  for extra in "${MSM_REPO}"/scripts/bench.d/*.sh; do
    [ -x "${extra}" ] || continue
    msm_log "running $(basename "${extra}")"
    "${extra}" "${out}" "${data}" "${map}" "${bin}" || msm_log "$(basename "${extra}") failed"
  done
fi

# 5. bench.json: what could be measured.
/usr/bin/python3 - "${out}" "${steps}" "${data}" "${map}" "${report}" "${profile}" \
    "${sessions}" "${seed}" <<'PY'
import glob, json, os, platform, sys, time
out, steps, data, map_dir, report_dir, profile, sessions, seed = sys.argv[1:9]

def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None

def size(path):
    return os.path.getsize(path) if os.path.isfile(path) else None

def cpu():
    try:
        for line in open('/proc/cpuinfo'):
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor()

bench = {'format': 'multisession_mapper_bench/1',
         'date_utc': time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime()),
         'machine': {'cpu': cpu(), 'cores': os.cpu_count(), 'kernel': platform.release()},
         'profile': profile, 'sessions': int(sessions), 'seed': int(seed),
         'paths': {'data': data, 'map': map_dir, 'report': report_dir},
         'not_available': []}
steps_json = {os.path.splitext(os.path.basename(p))[0]: load(p)
              for p in sorted(glob.glob(os.path.join(steps, '*.json')))}
for name, step in steps_json.items():
    if step and step.get('available') is False:
        bench['not_available'].append('%s: %s' % (name, step.get('reason')))

sim = steps_json.get('simulate') or {}
bags = []
index = None
try:
    import yaml
    with open(os.path.join(data, 'sessions.yaml')) as f:
        index = yaml.safe_load(f)
except (OSError, ImportError):
    index = None
if index:
    for s in index.get('sessions') or []:
        bags.append({'name': s.get('name'), 'bag_bytes': size(os.path.join(data, s.get('bag', ''))),
                     'scans': s.get('scans'), 'duration_s': s.get('duration_s'),
                     'route_length_m': s.get('route_length_m')})
bench['simulate'] = {'available': bool(index), 'wall_s': sim.get('wall_s'),
                     'reused': bool(sim.get('reused')), 'peak_rss_mb': sim.get('peak_rss_mb'),
                     'sessions': bags}

mapping = []
for name in sorted(k for k in steps_json if k.startswith('map_')):
    step = steps_json[name] or {}
    if step.get('available') is False:
        continue
    i = int(name.split('_')[1])
    duration = bags[i]['duration_s'] if i < len(bags) else None
    wall = step.get('wall_s')
    mapping.append({'session': bags[i]['name'] if i < len(bags) else name,
                    'wall_s': wall, 'peak_rss_mb': step.get('peak_rss_mb'),
                    'exit_status': step.get('exit_status'),
                    'realtime_factor': duration / wall if duration and wall else None})
bench['mapping'] = mapping

report = load(os.path.join(report_dir, 'report.json'))
ev = steps_json.get('evaluate') or {}
bench['evaluate'] = {'available': report is not None, 'wall_s': ev.get('wall_s')}
if report:
    bench['headline'] = {
        'sessions': [{k: s.get(k) for k in (
            'name', 'scans', 'ate_rmse_m', 'ate_rmse_map_fit_m', 'ate_rmse_aligned_m',
            'rpe_100m_pct', 'rpe_100m_deg', 'submaps_total', 'submaps_correct',
            'submaps_undefined_new',
            'submaps_undefined_missed', 'submaps_wrong', 'inter_loop_trans_err_median_m',
            'inter_loop_rot_err_median_deg', 'intra_loops_accepted', 'intra_loops_wrong')}
            | {'place_recognition': {k: (s.get('place_recognition') or {}).get(k) for k in (
                'f1max', 'recall_at_1', 'recall_at_5', 'max_recall_at_full_precision')}}
            for s in report.get('sessions', [])],
        'dynamics': report.get('dynamics'),
        'map': report.get('map'),
        'timing': report.get('timing'),
    }
    bench['warnings'] = report.get('warnings', [])

extra = {}
for path in sorted(glob.glob(os.path.join(out, 'bench.d', '*.json'))):
    extra[os.path.splitext(os.path.basename(path))[0]] = load(path)
bench['extra'] = extra

with open(os.path.join(out, 'bench.json'), 'w') as f:
    json.dump(bench, f, indent=2)
    f.write('\n')
print('bench.json written to %s' % os.path.join(out, 'bench.json'))
if bench['not_available']:
    print('not available yet:')
    for item in bench['not_available']:
        print('  - ' + item)
PY
