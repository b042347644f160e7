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
catkin_make -C "${MSM_WS}" --source "${MSM_SRC}" -j1 run_tests 2>&1 \
  | grep -vE '^\[ *[0-9]+%\] (Built target|Generating|Building)' || true

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
exit $(( status != 0 || failed != 0 ))
