#!/usr/bin/env bash
# Builds the package and its test suite with AddressSanitizer + UndefinedBehaviorSanitizer in
# its own workspace build/ws_asan (MSM_WS overrides) and runs every test there through
# scripts/test.sh: a sanitizer report fails the test that triggered it. The summary is the last
# lines, as for scripts/test.sh.
#   scripts/sanitize.sh            ASan + UBSan, the whole test suite
#   scripts/sanitize.sh --thread   ThreadSanitizer (build/ws_tsan), the gtests of the modules
#                                  that run threads: OdometryWorker, WorkerPool and its users
#                                  (the odometry's correspondence search), ParallelFor users
#                                  (inter-session matching, merge), the simulator; then both
#                                  rostests (mapping.test, bad_input.test) with the nodelet
#                                  manager under TSan: the /usr nodelet binary is not
#                                  instrumented, so libtsan is preloaded into it (launch prefix
#                                  from MSM_MANAGER_LAUNCH_PREFIX, see nodelets.launch) and it
#                                  loads the instrumented nodelets library of build/ws_tsan. Each
#                                  manager writes its reports to build/ws_tsan/tsan_rostest/;
#                                  any "WARNING: ThreadSanitizer" there fails the run, as does a
#                                  manager that did not run under TSan or a failed rostest.
#                                  --thread --rostests-only: skip the gtests;
#                                  MSM_TSAN_ROSTESTS="bad_input.test": only these rostests.
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
  tests=(odometry_worker_test worker_pool_test voxel_hash_map_test icp_registration_test
         odometry_test inter_session_matcher_test session_merger_test
         sim_campus_simulator_test dynamic_propagation_test)
  [ "${2:-}" = "--rostests-only" ] && tests=()
  # The nodelets library and the tool the mapping rostest simulates its bags with.
  make -C "${MSM_WS}/build" -j"${MSM_JOBS:-$(nproc)}" "${tests[@]}" multisession_mapper_nodelets \
    simulate_campus > "${MSM_WS}/tsan_build.log" 2>&1 \
    || msm_die "building the TSan tests failed (see ${MSM_WS}/tsan_build.log)"
  supp="${MSM_REPO}/scripts/lib/tsan.supp"
  # halt_on_error: the first race fails the test; second_deadlock_stack for lock-order reports.
  export TSAN_OPTIONS="${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:suppressions=${supp}}"
  failed=0
  for t in "${tests[@]}"; do
    msm_log "TSan: ${t}"
    if ! "${MSM_WS}/devel/lib/multisession_mapper/${t}" > "${MSM_WS}/${t}.tsan.log" 2>&1; then
      failed=$((failed + 1))
      grep -A30 -m1 'WARNING: ThreadSanitizer' "${MSM_WS}/${t}.tsan.log" \
        || tail -n 20 "${MSM_WS}/${t}.tsan.log"
    fi
  done
  [ ${#tests[@]} -eq 0 ] || echo "tsan: ${#tests[@]} test programs, ${failed} failed"

  # The rostests, nodelet manager under TSan. Not halt_on_error: every report of a run is kept
  # (log_path: one file per manager process, <prefix>.<pid>); verbosity=1 makes TSan write its
  # banner into that file, the proof that the manager really ran instrumented.
  libtsan="$(readlink -f "$(g++ -print-file-name=libtsan.so)")"
  [ -f "${libtsan}" ] || msm_die "libtsan.so not found (g++ -print-file-name=libtsan.so)"
  logs="${MSM_WS}/tsan_rostest"
  rm -rf "${logs}" && mkdir -p "${logs}"
  # ignore_noninstrumented_modules: the ROS / Boost / log4cxx libraries and the nodelet binary
  # are not instrumented; their atomics (message reference counts) and memory accesses are
  # invisible to TSan, so the interceptor calls they make (new/delete, memcpy, mutexes) report
  # races on messages freed after an unseen reference drop and lock-order inversions inside
  # roscpp's transport (352 reports in one run without it, 9 with it: see tsan.supp). Races in
  # our instrumented code are still reported (checked with a deliberate race).
  manager_options="halt_on_error=0:second_deadlock_stack=1:verbosity=1:ignore_noninstrumented_modules=1:suppressions=${supp}"
  symbolizer="$(command -v llvm-symbolizer || true)"
  [ -n "${symbolizer}" ] && manager_options="${manager_options}:external_symbolizer_path=${symbolizer}"
  rostests_failed=0
  read -r -a rostests <<< "${MSM_TSAN_ROSTESTS:-mapping.test bad_input.test}"
  for t in "${rostests[@]}"; do
    name="${t%.test}"
    msm_log "TSan: rostest ${t} (nodelet manager under TSan)"
    export MSM_MANAGER_LAUNCH_PREFIX="env LD_PRELOAD=${libtsan} TSAN_OPTIONS=${manager_options}:log_path=${logs}/${name}.manager"
    # The rostest's own processes (python, roslaunch, rosbag) stay uninstrumented.
    if ! rostest --text "${MSM_REPO}/launch/test/${t}" > "${logs}/${name}.rostest.log" 2>&1; then
      rostests_failed=$((rostests_failed + 1))
      echo "rostest ${t} failed under TSan:"
      tail -n 25 "${logs}/${name}.rostest.log"
    fi
    managers=$(grep -l 'Running under ThreadSanitizer' "${logs}/${name}".manager.* 2>/dev/null | wc -l)
    echo "  ${t}: ${managers} nodelet manager process(es) ran under TSan"
    if [ "${managers}" -lt 1 ]; then
      echo "  no TSan banner of a nodelet manager: it did not run under TSan"
      rostests_failed=$((rostests_failed + 1))
    fi
  done
  unset MSM_MANAGER_LAUNCH_PREFIX
  banners=$(grep -l 'Running under ThreadSanitizer' "${logs}"/*.manager.* 2>/dev/null | wc -l)
  warnings=$(cat "${logs}"/*.manager.* 2>/dev/null | grep -c 'WARNING: ThreadSanitizer' || true)
  if [ "${warnings}" -gt 0 ]; then
    grep -h -A40 -m1 'WARNING: ThreadSanitizer' "${logs}"/*.manager.* | head -n 60
    echo "(all reports: ${logs}/*.manager.*)"
  fi
  echo "tsan rostests: ${#rostests[@]} rostests, ${rostests_failed} failed; ${banners} manager process(es) under TSan, ${warnings} ThreadSanitizer warning(s)"
  exit $(( failed != 0 || rostests_failed != 0 || warnings != 0 ))
fi

export MSM_WS="${MSM_WS_ASAN:-${MSM_REPO}/build/ws_asan}"
# EIGEN_MALLOC_ALREADY_ALIGNED=1: under __SANITIZE_ADDRESS__ Eigen stops trusting malloc's
# 16-byte alignment and switches to its own aligned allocation (the pointer stored in front of
# the block), while Debian's PCL, built without ASan, uses plain malloc. Both meet in PCL's
# inline code (an FPFHEstimation destroyed in our code frees the VectorXf that libpcl
# allocated) and ASan reports a heap-buffer-overflow that a normal build does not have. ASan's
# malloc returns 16-byte aligned blocks on x86-64 (checked for every size 1..4999), so the
# normal build's assumption holds and both sides agree again.
flags="-fsanitize=address,undefined -fno-omit-frame-pointer -g -DEIGEN_MALLOC_ALREADY_ALIGNED=1"
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
