#!/usr/bin/env bash
# AddressSanitizer + UndefinedBehaviorSanitizer run of the ROS-free part: builds the core, io and
# sim libraries, dem_offline and the non-ROS gtests with -fsanitize=address,undefined in a
# workspace of its own (.catkin_ws_asan, git-ignored), then runs every one of those gtests and
# dem_offline on the bundled KITTI sample (sequence mode), with leak detection on, SGD_JOBS of them
# at a time. Any report (memory error, undefined behaviour, leak) or failing test fails the run.
# Only leaks inside third-party libraries may be suppressed: scripts/sanitizers/lsan.supp says
# which and why (none are needed today).
#
# Usage: scripts/run_sanitizers.sh     (SGD_ASAN_WS moves the workspace, SGD_JOBS sets the
#                                       build's -j and the number of tests run at once; default nproc)
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export PATH="/usr/bin:/bin:$PATH"
WS="${SGD_ASAN_WS:-$REPO/.catkin_ws_asan}"
JOBS="${SGD_JOBS:-$(nproc)}"
start=$(date +%s)
mkdir -p "$WS/src"
if [ ! -e "$WS/src/stereo_ground_dem" ]; then ln -s "$REPO" "$WS/src/stereo_ground_dem"; fi

SAN="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
# longest first, so that the parallel runs end together
TESTS=(test_estimators test_obstacles test_bad_input test_sim test_offline test_parser_fuzz test_traversability
       test_core test_io)
cd "$WS"
# -O1: readable reports and a build that fits the CI budget; NDEBUG as in Release. (-O2 runs the
# tests 1.4 times faster but takes 18 instead of 9-14 minutes to build: no net gain, 2026-12-06.)
# -g1: line tables only, all a report's stack trace needs (file:line of every frame), and a
# shorter build than full debug information.
catkin_make -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DCMAKE_CXX_FLAGS="$SAN" -DCMAKE_EXE_LINKER_FLAGS="$SAN" -DCMAKE_SHARED_LINKER_FLAGS="$SAN" \
  -DCATKIN_ENABLE_TESTING=ON -j"$JOBS" dem_offline sgd_render "${TESTS[@]}" > "$WS/build.log" 2>&1 \
  || { tail -n 60 "$WS/build.log"; echo "run_sanitizers: build failed (full log: $WS/build.log)"; exit 1; }
built=$(date +%s)
echo "run_sanitizers: build ok ($((built - start)) s)"

# detect_stack_use_after_return is off: it makes the estimator tests 1.5 times slower and the
# budget of the CI run (90 minutes on 2 cores, of which the main run takes 30-40) does not allow it.
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:check_initialization_order=1:strict_init_order=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$REPO/scripts/sanitizers/lsan.supp:print_suppressions=0"
BIN="$WS/devel/lib/stereo_ground_dem"
LOGS="$WS/logs"
rm -rf "$LOGS" "$WS/dem_offline_out"
mkdir -p "$LOGS"

# One job: runs the command from the repository, writes LOGS/name.log and LOGS/name.result.
job() {
  local name="$1"
  shift
  local t0 status=0
  t0=$(date +%s)
  (cd "$REPO" && /usr/bin/time -f "%U %S" -o "$LOGS/$name.cpu" "$@") > "$LOGS/$name.log" 2>&1 || status=$?
  if grep -qE "ERROR: (Address|Leak)Sanitizer|runtime error:" "$LOGS/$name.log"; then status=99; fi
  local cpu
  cpu=$(awk '{printf "%.0f", $1 + $2}' "$LOGS/$name.cpu" 2>/dev/null || echo "?")
  echo "$status $(( $(date +%s) - t0 )) $cpu" > "$LOGS/$name.result"
}
# Three accuracy tests over long rendered drives stay out of this run: under ASan at -O1 each took
# 12-13 minutes of a shard (28 shadow frames twice; four 20-frame drives; 40 shadow frames twice),
# half of the stage. The
# main test run asserts their figures; their code runs here in shorter tests: hypothesis screening
# (prealign_screen_iterations, default 3) in IncrementalEstimator.MovingShadowsAreTestedAfterTheCoarsestJointLevel
# and every tracked frame, GroundAttitudeEstimator in test_core's GroundAttitude.* and dem_offline.
# A fourth, IncrementalEstimator.SecondPassStartsFromThePredictionWhenItExplainsTheImagesBetter,
# took 13 minutes (two 40-frame shadow drives, one of them only printed); the second pass from the
# prediction runs here in MovingShadowsAreTestedAfterTheCoarsestJointLevel and the alternative
# start in SurfaceAligner.AnAlternativeStartIsTakenOnlyWhenClearlyCheaper. The flat road of
# Scenes/SyntheticSequence (5 minutes) runs the same code as its bump-and-curb drive, which stays.
# Six more, 3-9 minutes each under ASan (1,900 s of the stage's 4,300 CPU seconds; the whole CI run
# took 83-89 minutes of its 90 with them, 2026-12-06), are accuracy figures over drives whose code
# runs here in shorter tests:
#   Obstacles.MovingObjectsLeaveNoGhosts (30 frames, a crossing car): the moving cars of the
#     traffic drive, their obstacle masks and the map's clearing, in
#     IncrementalEstimator.AMapContinuedFromItsSavedStateEqualsOneRun, and
#     PhotometricResidualMap.FlagsAMovingObjectNotTheStaticRoad;
#   Obstacles.TraversabilityProbabilityAgainstTheTruth (15 frames): TraversabilityFilter's
#     probability in test_traversability, the obstacles beside a curb in
#     Obstacles.CurbAndStepStayStepsBesideObstacles;
#   IncrementalEstimator.DroppedFramesCostLittle (4 x 25 frames): the stamp gap's scaling in
#     test_bad_input's BadInput.JumpInTheStampsIsReportedAndTheRunGoesOn and
#     BadInput.DuplicatedStampUsesTheNominalPeriod;
#   IncrementalEstimator.TemporalPairsGoFinerOnSmallImages (2 x 40 half-width frames): the same
#     pixel loops at another pyramid level, run by every tracked frame;
#   OrthoTexture.MatchesTheRenderedAlbedoUnderAnExposureDrift (20 frames): OrthoTexture::update
#     on every frame of AMapContinuedFromItsSavedStateEqualsOneRun and of dem_offline below;
#   IncrementalEstimator.FineIterationsPerPass (2 x 4 shadow frames): the bounded passes are the
#     same Gauss-Newton loop as MovingShadowsAreTestedAfterTheCoarsestJointLevel's.
ASAN_SKIP="-IncrementalEstimator.HypothesesAreScreenedWithFewerIterations:IncrementalEstimator.PreAlignmentBeyondTheAccelerationBoundKeepsThePrediction:IncrementalEstimator.TextureMovingWithTheVehicleIsSkippedFromTheStart:GroundAttitude.FollowsTheTruthOnRenderedDrives:IncrementalEstimator.SecondPassStartsFromThePredictionWhenItExplainsTheImagesBetter:Scenes/SyntheticSequence.TrajectoryAndDemMatchTheTruth/FlatRoad"
ASAN_SKIP+=":Obstacles.MovingObjectsLeaveNoGhosts:Obstacles.TraversabilityProbabilityAgainstTheTruth"
ASAN_SKIP+=":IncrementalEstimator.DroppedFramesCostLittle:IncrementalEstimator.TemporalPairsGoFinerOnSmallImages"
ASAN_SKIP+=":OrthoTexture.MatchesTheRenderedAlbedoUnderAnExposureDrift:IncrementalEstimator.FineIterationsPerPass"
# The two long test binaries are split into gtest shards (test_estimators into 3 JOBS: its tests
# take 0-5 minutes each under ASan, and with only JOBS shards one of them ran 12 minutes longer
# than the other); a new job starts whenever one ends.
names=()
commands=()
for t in "${TESTS[@]}"; do
  if [ "$t" = test_estimators ] || [ "$t" = test_obstacles ]; then
    shards=$JOBS
    if [ "$t" = test_estimators ]; then shards=$((3 * JOBS)); fi
    for ((i = 0; i < shards; i++)); do
      names+=("$t.shard$i")
      commands+=("env GTEST_TOTAL_SHARDS=$shards GTEST_SHARD_INDEX=$i GTEST_FILTER=$ASAN_SKIP $BIN/$t")
    done
  else
    names+=("$t")
    commands+=("$BIN/$t")
  fi
done
names+=(dem_offline_sequence)
commands+=("$BIN/dem_offline --sequence data/kitti_seq06_sample --out $WS/dem_offline_out --quiet")
running=0
for k in "${!names[@]}"; do
  # shellcheck disable=SC2086  # the command is a list of words without spaces inside them
  job "${names[$k]}" ${commands[$k]} &
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then
    wait -n
    running=$((running - 1))
  fi
done
wait
failed=()
for name in "${names[@]}"; do
  read -r status wall cpu < "$LOGS/$name.result"
  if [ "$status" = 0 ]; then
    echo "run_sanitizers: $name clean ($wall s, cpu $cpu s)"
  else
    echo "run_sanitizers: $name FAILED ($wall s, log $LOGS/$name.log):"
    grep -E -A25 "ERROR: (Address|Leak)Sanitizer|runtime error:|\[  FAILED  \]" "$LOGS/$name.log" | head -n 60 \
      || tail -n 30 "$LOGS/$name.log"
    failed+=("$name")
  fi
done
echo "run_sanitizers: $(( $(date +%s) - start )) s in all (build $((built - start)) s, tests $(( $(date +%s) - built )) s)"
if [ ${#failed[@]} -gt 0 ]; then
  echo "run_sanitizers: ${#failed[@]} failed: ${failed[*]}"
  exit 1
fi
echo "run_sanitizers: all clean"
