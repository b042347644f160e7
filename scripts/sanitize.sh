#!/usr/bin/env bash
# Builds the package and its test suite with AddressSanitizer + UndefinedBehaviorSanitizer in
# its own workspace build/ws_asan (MSM_WS overrides) and runs every test there through
# scripts/test.sh: a sanitizer report fails the test that triggered it. The summary is the last
# lines, as for scripts/test.sh.
#   scripts/sanitize.sh            ASan + UBSan, the whole test suite
#   scripts/sanitize.sh --thread   ThreadSanitizer (build/ws_tsan), the gtests of the modules
#                                  that run threads: OdometryWorker, ParallelFor users
#                                  (inter-session matching, merge), the simulator
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

if [ "${1:-}" = "--thread" ]; then
  export MSM_WS="${MSM_WS_TSAN:-${MSM_REPO}/build/ws_tsan}"
  flags="-fsanitize=thread -fno-omit-frame-pointer -g"
  msm_install_deps
  CMAKE_BUILD_TYPE="${CMAKE_BUILD_TYPE:-RelWithDebInfo}" msm_build \
    -DCMAKE_CXX_FLAGS="${flags}" -DCMAKE_C_FLAGS="${flags}" \
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=thread"
  msm_source_workspace
  tests=(odometry_worker_test inter_session_matcher_test session_merger_test
         sim_campus_simulator_test)
  make -C "${MSM_WS}/build" -j"${MSM_JOBS:-$(nproc)}" "${tests[@]}" > "${MSM_WS}/tsan_build.log" 2>&1 \
    || msm_die "building the TSan tests failed (see ${MSM_WS}/tsan_build.log)"
  # halt_on_error: the first race fails the test; second_deadlock_stack for lock-order reports.
  export TSAN_OPTIONS="${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:suppressions=${MSM_REPO}/scripts/lib/tsan.supp}"
  failed=0
  for t in "${tests[@]}"; do
    msm_log "TSan: ${t}"
    if ! "${MSM_WS}/devel/lib/multisession_mapper/${t}" > "${MSM_WS}/${t}.tsan.log" 2>&1; then
      failed=$((failed + 1))
      grep -A30 -m1 'WARNING: ThreadSanitizer' "${MSM_WS}/${t}.tsan.log" \
        || tail -n 20 "${MSM_WS}/${t}.tsan.log"
    fi
  done
  echo "tsan: ${#tests[@]} test programs, ${failed} failed"
  exit $(( failed != 0 ))
fi

export MSM_WS="${MSM_WS_ASAN:-${MSM_REPO}/build/ws_asan}"
flags="-fsanitize=address,undefined -fno-omit-frame-pointer -g"
msm_install_deps
# The flags are kept in the workspace's CMake cache, so test.sh's own build step keeps them.
CMAKE_BUILD_TYPE="${CMAKE_BUILD_TYPE:-RelWithDebInfo}" msm_build \
  -DCMAKE_CXX_FLAGS="${flags}" -DCMAKE_C_FLAGS="${flags}" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined"
# halt_on_error: a UBSan report is a failure, not a warning. Leak checking stays on.
# verify_asan_link_order=0: nodelets (instrumented plugins) are loaded by the uninstrumented
# nodelet manager.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:verify_asan_link_order=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
msm_log "running the test suite under ASan + UBSan (${MSM_WS})"
exec "${MSM_REPO}/scripts/test.sh"
