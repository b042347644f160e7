#!/usr/bin/env bash
# Installs what is missing, builds, runs every gtest, pytest and rostest of the package, and
# exits non-zero on any failure or when no test ran. The last lines are the summary.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/common.sh"

msm_install_deps
msm_build
msm_source_workspace

results="${MSM_WS}/build/test_results"
rm -rf "${results}"
msm_log "building the tests"
set +e
catkin_make -C "${MSM_WS}" --source "${MSM_SRC}" -j"${MSM_JOBS:-$(nproc)}" tests 2>&1 \
  | grep -vE '^\[ *[0-9]+%\] (Built target|Generating|Building)'
build_status=${PIPESTATUS[0]}
set -e
[ "${build_status}" -eq 0 ] || msm_die "building the tests failed"
msm_log "running the tests"
# catkin_make run_tests exits 0 even when tests fail (quirk 3): judge by catkin_test_results.
# -k: a test target that errors must not keep the others from running.
catkin_make -C "${MSM_WS}" --source "${MSM_SRC}" -j1 run_tests -k 2>&1 \
  | grep -vE '^\[ *[0-9]+%\] (Built target|Generating|Building)' || true
# Every registered test target must leave a readable result file.
expected="$(make -C "${MSM_WS}/build" help 2>/dev/null \
  | grep -oE 'run_tests_multisession_mapper_(gtest|pytest|rostest|fuzz)_[A-Za-z0-9_.-]+' \
  | sort -u | wc -l)"
produced="$(find "${results}" -name '*.xml' 2>/dev/null | wc -l)"

msm_log "test results"
set +e
summary="$(catkin_test_results --all "${results}" 2>&1)"
status=$?
set -e
printf '%s\n' "${summary}" | grep -vE ': [0-9]+ tests, 0 errors, 0 failures' | grep -v '^$' || true
last="$(printf '%s\n' "${summary}" | tail -n 1)"
read -r passed failed skipped < <(/usr/bin/python3 "${MSM_REPO}/scripts/lib/count_test_results.py" "${results}")
total=$((passed + failed + skipped))
echo "tests: ${passed} passed, ${failed} failed, ${skipped} skipped"
echo "${last}"
if [ "${total}" -eq 0 ]; then
  msm_die "no test ran"
fi
if printf '%s\n' "${summary}" | grep -q '^Skipping'; then
  msm_die "a test result file could not be read (see 'Skipping' above)"
fi
if [ "${produced}" -lt "${expected}" ]; then
  msm_die "${expected} test targets are registered but only ${produced} result files were written"
fi
exit $(( status != 0 || failed != 0 ))
