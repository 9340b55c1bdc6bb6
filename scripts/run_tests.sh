#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds, runs every gtest and rostest, and ends with
# catkin_test_results' summary line. Exits non-zero when any test fails.
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export PATH="/usr/bin:/bin:$PATH"
bash "$REPO/scripts/install_deps.sh"
bash "$REPO/scripts/build.sh"
WS="${SGD_WS:-$REPO/.catkin_ws}"
cd "$WS"
rm -rf "$WS/build/test_results"
set +e
catkin_make run_tests -j"${SGD_JOBS:-$(nproc)}" > "$WS/test.log" 2>&1
status=$?
set -e
grep -E "^\[ *(RUN|OK|FAILED|PASSED) *\]|tests? ran|FAILURE|Failure" "$WS/test.log" | grep -v "^\[ RUN" | tail -n 200 || true
[ $status -eq 0 ] || { tail -n 80 "$WS/test.log"; echo "run_tests: catkin_make run_tests failed ($status)"; }
# Every command of README.md and docs/ros.md, run verbatim on the built workspace (about 2 min);
# its JUnit file is counted by catkin_test_results below.
mkdir -p "$WS/build/test_results/stereo_ground_dem"
set +e
/usr/bin/python3 "$REPO/scripts/check_doc_commands.py" \
  --junit "$WS/build/test_results/stereo_ground_dem/doc_commands.xml" > "$WS/doc_commands.log" 2>&1
grep -E "^(FAIL|doc_commands:)" "$WS/doc_commands.log"
catkin_test_results "$WS/build/test_results"
results=$?
set -e
# catkin_make run_tests returns 0 even when tests fail; catkin_test_results does not, and a build
# error in a test target shows only in run_tests' status: fail on either.
if [ $status -ne 0 ] || [ $results -ne 0 ]; then exit 1; fi
