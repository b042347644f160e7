#!/usr/bin/env bash
# Builds the package and its test suite with AddressSanitizer + UndefinedBehaviorSanitizer in
# its own workspace build/ws_asan (MSM_WS overrides) and runs every test there through
# scripts/test.sh: a sanitizer report fails the test that triggered it. The summary is the last
# lines, as for scripts/test.sh.
#   scripts/sanitize.sh
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

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
