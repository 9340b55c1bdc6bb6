// sgd_benchmark: speed of the pipeline at full KITTI resolution (1226 x 370) on the bundled sample.
//
//   sgd_benchmark [--benchmark_repetitions=5] [--benchmark_report_aggregates_only=true]
//
// Google Benchmark reports wall-clock ms per iteration; every benchmark processes real frames of
// KITTI odometry sequence 06 (data/kitti_seq06_sample).
#include <benchmark/benchmark.h>

#include <memory>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utils/logger.hpp>

#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/SkylineMask.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/TraversabilityFilter.hpp"
#include "stereo_ground_dem/io/AllocatorTuning.hpp"
#include "stereo_ground_dem/io/KittiSequence.hpp"

using namespace stereo_ground_dem;

namespace {

struct Sample {
  KittiSequence seq;
  std::vector<cv::Mat> left, right;
  PipelineOptions options;
  static const Sample& get() {
    static const Sample s = [] {
      Sample x{KittiSequence::open(std::string(SGD_SOURCE_DIR) + "/data/kitti_seq06_sample"), {}, {}, {}};
      x.options = ParameterTable::load(std::string(SGD_SOURCE_DIR) + "/config/kitti.yaml");
      for (int i = 0; i < x.seq.size(); ++i) {
        cv::Mat l, r;
        x.seq.read(i, &l, &r);
        x.left.push_back(l);
        x.right.push_back(r);
      }
      return x;
    }();
    return s;
  }
};

void BM_IncrementalFrame(benchmark::State& state) {
  const Sample& s = Sample::get();
  std::unique_ptr<IncrementalEstimator> est;
  int next = 0;
  // Untimed: the initializing frame and the first tracked one, which has no velocity yet and runs
  // the motion search (BM_FirstTrackedFrame); the timed frames are the steady state.
  auto restart = [&] {
    est = std::make_unique<IncrementalEstimator>(s.seq.rig(), s.options.estimator);
    est->processFrame(s.left[0], s.right[0], s.seq.stamp(0));
    est->processFrame(s.left[1], s.right[1], s.seq.stamp(1));
    next = 2;
  };
  restart();
  int failures = 0;
  // Where the time goes (ms per frame, averaged): motion-only pre-alignment, occlusion reasoning,
  // the joint mesh levels; the rest is pyramids, window set-up, fusion and bookkeeping.
  double prealign_ms = 0.0, obstacle_ms = 0.0, joint_ms = 0.0, other_ms = 0.0;
  for (auto _ : state) {
    const FrameResult r = est->processFrame(s.left[static_cast<size_t>(next)], s.right[static_cast<size_t>(next)],
                                            s.seq.stamp(next));
    failures += r.status != FrameStatus::kTracked;
    // The estimator's own split (FrameResult): the report count per stage varies (the starts of
    // the search, a repeated level after the consistency test).
    prealign_ms += r.prealign_ms;
    joint_ms += r.joint_ms;
    obstacle_ms += r.obstacle_ms;
    other_ms += r.time_ms - r.prealign_ms - r.joint_ms - r.obstacle_ms;
    if (++next == s.seq.size()) {
      state.PauseTiming();
      restart();
      state.ResumeTiming();
    }
  }
  state.counters["failures"] = failures;
  state.counters["prealign_ms"] = benchmark::Counter(prealign_ms, benchmark::Counter::kAvgIterations);
  state.counters["obstacles_ms"] = benchmark::Counter(obstacle_ms, benchmark::Counter::kAvgIterations);
  state.counters["joint_levels_ms"] = benchmark::Counter(joint_ms, benchmark::Counter::kAvgIterations);
  state.counters["other_ms"] = benchmark::Counter(other_ms, benchmark::Counter::kAvgIterations);
  state.SetLabel("tracked frame, 3 image pairs, full resolution");
}
BENCHMARK(BM_IncrementalFrame)->Unit(benchmark::kMillisecond)->MinTime(3.0);

void BM_FirstTrackedFrame(benchmark::State& state) {
  // The frame after initialization (or a failure): no velocity, so the motion search scores the
  // steps and pre-aligns the candidates before the joint levels.
  const Sample& s = Sample::get();
  int failures = 0;
  double prealign_ms = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    IncrementalEstimator est(s.seq.rig(), s.options.estimator);
    est.processFrame(s.left[0], s.right[0], s.seq.stamp(0));
    state.ResumeTiming();
    const FrameResult r = est.processFrame(s.left[1], s.right[1], s.seq.stamp(1));
    failures += r.status != FrameStatus::kTracked;
    prealign_ms += r.prealign_ms;
  }
  state.counters["failures"] = failures;
  state.counters["prealign_ms"] = benchmark::Counter(prealign_ms, benchmark::Counter::kAvgIterations);
  state.SetLabel("first tracked frame (no velocity: motion search), full resolution");
}
BENCHMARK(BM_FirstTrackedFrame)->Unit(benchmark::kMillisecond)->MinTime(3.0);

void BM_StereoMode(benchmark::State& state) {
  const Sample& s = Sample::get();
  const StereoEstimator est(s.seq.rig(), s.options.estimator.stereo);
  for (auto _ : state) {
    const StereoResult r = est.estimate(s.left[0], s.right[0]);
    benchmark::DoNotOptimize(r.heights.data());
  }
  state.SetLabel("one pair from scratch (start-up plane fit + 4 mesh levels)");
}
BENCHMARK(BM_StereoMode)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_Pyramids(benchmark::State& state) {
  const Sample& s = Sample::get();
  const StereoEstimator est(s.seq.rig(), s.options.estimator.stereo);
  for (auto _ : state) {
    const ImagePyramid l = est.makePyramid(s.left[0]), r = est.makePyramid(s.right[0]);
    benchmark::DoNotOptimize(l.level(0).image.data);
  }
  state.SetLabel("two images: grey, blur, 4 levels, gradients");
}
BENCHMARK(BM_Pyramids)->Unit(benchmark::kMillisecond);

void BM_SkylineMask(benchmark::State& state) {
  const Sample& s = Sample::get();
  const StereoEstimator est(s.seq.rig(), s.options.estimator.stereo);
  const ImagePyramid l = est.makePyramid(s.left[0]);
  const SkylineMask mask(s.options.estimator.skyline);
  for (auto _ : state) {
    const std::vector<cv::Mat> m = mask.compute(l, s.options.estimator.temporal_finest_level);
    benchmark::DoNotOptimize(m.data());
  }
  state.SetLabel("the left pyramid, the temporal pairs' levels (once per tracked frame)");
}
BENCHMARK(BM_SkylineMask)->Unit(benchmark::kMillisecond);

void BM_ObstacleDetector(benchmark::State& state) {
  const Sample& s = Sample::get();
  const StereoEstimator est(s.seq.rig(), s.options.estimator.stereo);
  const ImagePyramid l = est.makePyramid(s.left[0]), r = est.makePyramid(s.right[0]);
  const StereoResult sr = est.estimate(l, r);
  for (auto _ : state) {
    const ObstacleMask m = est.detectObstacles(l, r, sr.grid, sr.heights, sr.ground_T_camera.inverse(), sr.photometric);
    benchmark::DoNotOptimize(m.pixels);
  }
}
BENCHMARK(BM_ObstacleDetector)->Unit(benchmark::kMillisecond);

void BM_Traversability(benchmark::State& state) {
  const Sample& s = Sample::get();
  const StereoEstimator est(s.seq.rig(), s.options.estimator.stereo);
  const StereoResult sr = est.estimate(s.left[0], s.right[0]);
  const TraversabilityFilter filter(s.options.traversability);
  for (auto _ : state) {
    const TraversabilityLayers t = filter.compute(sr.grid, sr.heights);
    benchmark::DoNotOptimize(t.traversability.data);
  }
  state.SetLabel(std::to_string(sr.grid.rows) + " x " + std::to_string(sr.grid.cols) + " vertices");
}
BENCHMARK(BM_Traversability)->Unit(benchmark::kMillisecond);

void BM_SgbmThreeWay(benchmark::State& state) {
  // The dense stereo this package's DEM replaces, as peers run it: OpenCV StereoSGBM, 3-way, 128
  // disparities, 5x5 blocks, P1 8*25, P2 32*25 (scripts/compare_sgbm.py), on the same pair, with
  // as many threads as the estimator (num_threads). A peer pipeline adds its motion estimate.
  const Sample& s = Sample::get();
  const int threads_before = cv::getNumThreads();
  cv::setNumThreads(s.options.estimator.stereo.aligner.num_threads);
  cv::Mat l8, r8, disparity;
  s.left[0].convertTo(l8, CV_8U);
  s.right[0].convertTo(r8, CV_8U);
  const cv::Ptr<cv::StereoSGBM> sgbm =
      cv::StereoSGBM::create(0, 128, 5, 8 * 25, 32 * 25, 1, 0, 10, 100, 2, cv::StereoSGBM::MODE_SGBM_3WAY);
  for (auto _ : state) {
    sgbm->compute(l8, r8, disparity);
    benchmark::DoNotOptimize(disparity.data);
  }
  cv::setNumThreads(threads_before);
  state.SetLabel("OpenCV StereoSGBM 3-way, one pair, full resolution");
}
BENCHMARK(BM_SgbmThreeWay)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

int main(int argc, char** argv) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  // Per-frame buffers of a few MB are reused instead of being mapped and zeroed anew each frame.
  AllocatorTuning::apply();  // as dem_offline and the nodelet
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
