#!/usr/bin/env bash
# Fuzzes the map loader (manifest, submap PCD, pose graph, descriptor database, whole map
# directory; test/fuzz/README.md) with libFuzzer under AddressSanitizer + UndefinedBehavior-
# Sanitizer, in its own clang build tree build/ws_fuzz (MSM_FUZZ_WS overrides).
#   scripts/fuzz.sh --short [--junit FILE]  a fixed number of executions per target from the
#                                           committed seeds (what scripts/test.sh runs)
#   scripts/fuzz.sh --long [--seconds N]    N seconds per target (default 600); new inputs are
#                                           kept in build/fuzz_corpus/<target>
#   scripts/fuzz.sh --build                 only build the targets
# A crashing input is saved in build/fuzz_crashes/<target>/; the script then exits 1. Turn each
# one into a regression test (test/map_store_fuzz_regression_test.cpp) and fix the loader.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

mode=""
junit=""
seconds=600
while [ $# -gt 0 ]; do
  case "$1" in
    --short|--long|--build) mode="${1#--}" ;;
    --junit) junit="$2"; shift ;;
    --seconds) seconds="$2"; shift ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    *) msm_die "unknown argument '$1' (see --help)" ;;
  esac
  shift
done
[ -n "${mode}" ] || msm_die "give --short, --long or --build (see --help)"

TARGETS=(fuzz_manifest fuzz_submap_pcd fuzz_graph_g2o fuzz_descriptor_database fuzz_map_directory)
# Executions per target in --short mode: about 100 s for all on a loaded 2-core machine
# (the map targets write a map directory per execution: ~30-120/s; the database target
# recomputes a 288-dimensional PCA per load: ~5/s; the pose graph target ~5000/s).
declare -A SHORT_RUNS=(
  [fuzz_manifest]=2000 [fuzz_submap_pcd]=1500 [fuzz_graph_g2o]=30000
  [fuzz_descriptor_database]=300 [fuzz_map_directory]=2000)

command -v clang++ >/dev/null || msm_die "clang++ is missing: apt-get install clang libclang-rt-14-dev"
ws="${MSM_FUZZ_WS:-${MSM_REPO}/build/ws_fuzz}"
# Run from scripts/test.sh (inside catkin's make): keep the outer make's jobserver out.
unset MAKEFLAGS MFLAGS MAKELEVEL
mkdir -p "${ws}/build"
touch "${MSM_REPO}/build/CATKIN_IGNORE" 2>/dev/null || true
if [ ! -f "${ws}/build/CMakeCache.txt" ]; then
  msm_log "configuring the fuzz build in ${ws} (clang, ASan + UBSan)"
  cmake -S "${MSM_REPO}" -B "${ws}/build" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMSM_FUZZ=ON -DCATKIN_ENABLE_TESTING=OFF \
    -DCATKIN_DEVEL_PREFIX="${ws}/devel" -DPYTHON_EXECUTABLE=/usr/bin/python3 >"${ws}/configure.log" 2>&1 \
    || { tail -20 "${ws}/configure.log"; msm_die "configuring the fuzz build failed"; }
fi
msm_log "building the fuzz targets"
cmake --build "${ws}/build" --target msm_fuzz_targets -- -j"${MSM_JOBS:-$(nproc)}" 2>&1 \
  | grep -vE '^\[ *[0-9]+%\] (Built target|Building)' || true
for t in "${TARGETS[@]}"; do
  [ -x "${ws}/devel/lib/multisession_mapper/${t}" ] || msm_die "building ${t} failed"
done
[ "${mode}" = "build" ] && exit 0

# tmpfs when there is one: the map targets write a small map directory per execution.
scratch="$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d)"
trap 'rm -rf "${scratch}"' EXIT
export TMPDIR="${scratch}"   # the targets' scratch folders go there
export ASAN_OPTIONS="abort_on_error=1:detect_leaks=1:allocator_may_return_null=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
crashes_root="${MSM_REPO}/build/fuzz_crashes"
failed=0
crashed=0
cases=""
for t in "${TARGETS[@]}"; do
  seeds="${MSM_REPO}/test/fuzz/corpus/${t}"
  crashes="${crashes_root}/${t}"
  mkdir -p "${crashes}"
  if [ "${mode}" = "short" ]; then
    corpus="${scratch}/corpus_${t}"
    limit=(-runs="${SHORT_RUNS[${t}]}" -seed=1)
  else
    corpus="${MSM_REPO}/build/fuzz_corpus/${t}"
    limit=(-max_total_time="${seconds}")
  fi
  mkdir -p "${corpus}"
  log="${scratch}/${t}.log"
  start=$(date +%s.%N)
  set +e
  "${ws}/devel/lib/multisession_mapper/${t}" "${limit[@]}" -max_len=65536 -timeout=20 -rss_limit_mb=2048 \
    -artifact_prefix="${crashes}/" -print_final_stats=1 "${corpus}" "${seeds}" >"${log}" 2>&1
  rc=$?
  set -e
  elapsed=$(awk -v a="${start}" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
  execs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "${log}" | grep -oE '[0-9]+$' || echo 0)
  cov=$(grep -oE 'cov: [0-9]+' "${log}" | tail -1 | grep -oE '[0-9]+' || echo 0)
  if [ ${rc} -eq 0 ]; then
    printf '%-26s ok     %8s executions  %6s s  coverage %s\n' "${t}" "${execs}" "${elapsed}" "${cov}"
    cases+="<testcase classname=\"fuzz\" name=\"${t}\" time=\"${elapsed}\"/>"
  else
    failed=1
    crashed=$((crashed + 1))
    printf '%-26s CRASH  (exit %d) after %s executions; input saved in %s\n' "${t}" "${rc}" "${execs}" "${crashes}"
    grep -E 'ERROR|runtime error|SUMMARY|#[0-9]+ 0x' "${log}" | head -25
    detail="$(grep -E 'ERROR|runtime error|SUMMARY' "${log}" | head -5 | sed 's/&/\&amp;/g; s/</\&lt;/g; s/>/\&gt;/g; s/"/\&quot;/g')"
    cases+="<testcase classname=\"fuzz\" name=\"${t}\" time=\"${elapsed}\"><failure message=\"crash, input in build/fuzz_crashes/${t}\">${detail}</failure></testcase>"
  fi
done
if [ -n "${junit}" ]; then
  mkdir -p "$(dirname "${junit}")"
  # catkin_test_results needs the errors and failures attributes.
  printf '<?xml version="1.0" encoding="UTF-8"?>\n<testsuite name="fuzz_map_loader" tests="%d" errors="0" failures="%d" skipped="0">%s</testsuite>\n' \
    "${#TARGETS[@]}" "${crashed}" "${cases}" >"${junit}"
fi
exit ${failed}
