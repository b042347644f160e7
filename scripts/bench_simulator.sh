#!/usr/bin/env bash
# Benchmark of the simulator (issue 3): times `simulate_campus` for the small and the campus
# profile (3 sessions each, fixed seed) and prints wall/CPU time, per-sweep simulation cost and
# the bag size per session. A benchmark, not a test: it asserts nothing and no test runs it.
#
# usage: MSM_WS=build/ws scripts/bench_simulator.sh [small] [campus]   (default: both)
# Data goes to build/bench_data/sim_<profile> (git-ignored); campus bags are ~1-2 GB each and
# are deleted after measuring unless MSM_KEEP_BENCH_DATA=1.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

bin="${MSM_WS}/devel/lib/multisession_mapper"
[ -x "${bin}/simulate_campus" ] || msm_die "${bin}/simulate_campus not built: run scripts/build.sh"
out_root="${MSM_REPO}/build/bench_data"
mkdir -p "${out_root}"
profiles=("$@")
[ ${#profiles[@]} -gt 0 ] || profiles=(small campus)
seed="${MSM_BENCH_SEED:-1}"
threads="${MSM_BENCH_THREADS:-$(nproc)}"

for profile in "${profiles[@]}"; do
  out="${out_root}/sim_${profile}"
  rm -rf "${out}"
  log="${out_root}/sim_${profile}.log"
  msm_log "simulate_campus --profile ${profile} --sessions 3 --seed ${seed} --threads ${threads}"
  /usr/bin/time -f "%e %U %S %M" -o "${out_root}/sim_${profile}.time" \
    "${bin}/simulate_campus" --profile "${profile}" --sessions 3 --seed "${seed}" \
    --threads "${threads}" --out "${out}" 2> >(tee "${log}" >&2)
  read -r wall user sys rss_kb < "${out_root}/sim_${profile}.time"
  echo
  echo "== ${profile} x3 (seed ${seed}, ${threads} threads, $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg))"
  echo "wall time: ${wall} s   CPU: user ${user} s + sys ${sys} s   peak RSS: $((rss_kb / 1024)) MB"
  # Per-session lines printed by the tool: sweeps, duration, route, bag size, ms/sweep.
  tr '\r' '\n' < "${log}" | grep -E '^  s[0-9]+: [0-9]+ sweeps,' || true
  for bag in "${out}"/*.bag; do
    printf '%s: %s\n' "$(basename "${bag}")" "$(du -h "${bag}" | cut -f1)"
  done
  echo "total on disk: $(du -sh "${out}" | cut -f1)"
  if [ "${profile}" = "campus" ] && [ "${MSM_KEEP_BENCH_DATA:-0}" != "1" ]; then
    rm -f "${out}"/*.bag
    echo "(campus bags deleted; set MSM_KEEP_BENCH_DATA=1 to keep them)"
  fi
done
