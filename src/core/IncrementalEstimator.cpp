#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/PoseSearch.hpp"
#include "stereo_ground_dem/SurfaceIncidence.hpp"

#include <Eigen/Dense>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "stereo_ground_dem/TemporalConsistency.hpp"
#include <sstream>
#include <stdexcept>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace stereo_ground_dem {

const char* toString(FrameStatus s) {
  switch (s) {
    case FrameStatus::kInitialized: return "initialized";
    case FrameStatus::kTracked: return "tracked";
    case FrameStatus::kRecovered: return "recovered";
    case FrameStatus::kFailed: return "failed";
    case FrameStatus::kRejectedInput: return "rejected_input";
  }
  return "?";
}

bool IncrementalEstimatorOptions::isValid(std::string* why) const {
  auto bad = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  std::string w;
  if (!stereo.isValid(&w)) return bad("stereo: " + w);
  ElevationMapOptions m = map;
  m.resolution_m = stereo.grid_resolution_m;
  if (!m.isValid(&w)) return bad("map: " + w);
  if (!(prior_weight >= 0.0)) return bad("prior_weight must be >= 0");
  if (tracking_levels < 1 || tracking_levels > stereo.mesh_levels) return bad("tracking_levels must be in 1..mesh_levels");
  if (temporal_finest_level < 0 || temporal_finest_level >= tracking_levels) {
    return bad("temporal_finest_level must be in 0..tracking_levels-1");
  }
  if (!(min_temporal_width_px >= 0) || min_temporal_width_px > 100000) {
    return bad("min_temporal_width_px must be in 0..100000");
  }
  if (iterations_per_level < 1 || fine_iterations < 1) return bad("iterations_per_level and fine_iterations must be >= 1");
  if (stereo_fine_iterations < 0 || repeat_iterations < 0) return bad("stereo_fine_iterations and repeat_iterations must be >= 0");
  if (!(nominal_frame_period_s > 0.0)) return bad("nominal_frame_period_s must be > 0");
  if (!check.isValid(&w)) return bad(w);
  if (!skyline.isValid(&w)) return bad(w);
  if (!temporal_visibility.isValid(&w)) return bad(w);
  if (!far_seeds.isValid(&w)) return bad(w);
  if (!rising_seeds.isValid(&w)) return bad(w);
  if (reinit_after_failures < 1) return bad("reinit_after_failures must be >= 1");
  if (prealign_level < 0 || prealign_iterations < 0 || prealign_refine_iterations < 0 || prealign_screen_iterations < 0) {
    return bad("prealign_level, prealign_iterations, prealign_refine_iterations and prealign_screen_iterations must be >= 0");
  }
  if (!(max_init_std_m > 0.0)) return bad("max_init_std_m must be > 0");
  if (rectification_startup_pairs < 0 || rectification_check_period_frames < 0) {
    return bad("rectification_startup_pairs and rectification_check_period_frames must be >= 0");
  }
  if (!(max_acceleration_mps2 >= 0.0) || !std::isfinite(max_acceleration_mps2)) {
    return bad("max_acceleration_mps2 must be finite and >= 0");
  }
  if (!(hypothesis_accept_ratio >= 1.0) || search_candidates < 1 || !(hypothesis_win_ratio > 0.0 && hypothesis_win_ratio <= 1.0)) {
    return bad("need hypothesis_accept_ratio >= 1, 0 < hypothesis_win_ratio <= 1 and search_candidates >= 1");
  }
  if (!(motion_search_step_m > 0.0) || !(motion_search_max_m >= motion_search_min_m)) {
    return bad("need motion_search_step_m > 0 and motion_search_max_m >= motion_search_min_m");
  }
  return true;
}

namespace {
ElevationMapOptions mapOptions(const IncrementalEstimatorOptions& o) {
  ElevationMapOptions m = o.map;
  m.resolution_m = o.stereo.grid_resolution_m;
  return m;
}
const IncrementalEstimatorOptions& validated(const IncrementalEstimatorOptions& o) {
  std::string why;
  if (!o.isValid(&why)) throw std::invalid_argument("IncrementalEstimatorOptions: " + why);
  return o;
}
// ORs `masks` (per pyramid level) into `into`, level by level: an empty level takes a copy (never
// a shared buffer: `into` is OR-ed in place later), masks not the size of `pyramid`'s level or
// empty add nothing.
void addMasks(const std::vector<cv::Mat>& masks, const ImagePyramid& pyramid, std::vector<cv::Mat>* into) {
  const size_t n = std::min(masks.size(), static_cast<size_t>(pyramid.levels()));
  if (into->size() < n) into->resize(n);
  for (size_t l = 0; l < n; ++l) {
    if (masks[l].empty() || masks[l].size() != pyramid.level(static_cast<int>(l)).image.size()) continue;
    cv::Mat& m = (*into)[l];
    if (m.empty()) m = masks[l].clone();
    else cv::bitwise_or(m, masks[l], m);
  }
}
}  // namespace

IncrementalEstimator::IncrementalEstimator(const StereoRig& rig, const IncrementalEstimatorOptions& options)
    : rig_(rig), options_(validated(options)), stereo_(rig, options.stereo), rectification_(options.stereo.rectification), map_(mapOptions(options)),
      predictor_(predictorOptions()), check_(options.check), skyline_(options.skyline) {}

MotionPredictorOptions IncrementalEstimator::predictorOptions() const {
  MotionPredictorOptions m;
  m.nominal_frame_period_s = options_.nominal_frame_period_s;
  m.search_min_m = options_.motion_search_min_m;
  m.search_max_m = options_.motion_search_max_m;
  m.search_step_m = options_.motion_search_step_m;
  m.search_max_reverse_m = options_.motion_search_max_reverse_m;
  m.rotation_step_rad = options_.rotation_hypothesis_rad;
  return m;
}

bool IncrementalEstimator::rectificationDue(int frame_index) const {
  // The misalignment is a property of the rig: measured on the first frames, then now and then
  // (it may drift with temperature), not on every frame.
  const int every = options_.rectification_check_period_frames;
  if (!options_.stereo.model_rectification) return false;
  if (rectification_.pairs() < options_.rectification_startup_pairs) return true;
  return every > 0 && frame_index % every == 0;
}

void IncrementalEstimator::addPairCheck(const StereoPairCheck& check) {
  if (!check.ok()) return;
  rectification_.accumulate(check);
  stereo_.setRectification(stereo_.modelled(rectification_.estimate()));
}

void IncrementalEstimator::reset() {
  rectification_.reset();
  stereo_.clearRectification();
  map_.clear();
  initialized_ = false;
  predictor_.reset();
  residual_level_ = prealign_level_ = temporal_residual_level_ = observed_level_ = 0.0;
  prev_left_.reset();
  prev_right_.reset();
  prev_obstacles_.clear();
  prev_moving_.clear();
  carried_moving_.clear();
  last_left_level0_.release();
  consecutive_failures_ = 0;
}

EstimatorState IncrementalEstimator::state() const {
  EstimatorState s;
  s.initialized = initialized_;
  s.frame_counter = frame_counter_;
  s.ground_T_camera0 = ground_T_camera0_;
  s.ground_T_camera = ground_T_camera_;
  s.last_camera_T_ground = predictor_.lastPose();
  s.last_stamp_s = predictor_.lastStamp();
  s.velocity = predictor_.velocity();
  s.velocity_gap_s = predictor_.lastGap();
  s.velocity_known = predictor_.velocityKnown();
  s.residual_level_grey = residual_level_;
  s.temporal_residual_level_grey = temporal_residual_level_;
  s.observed_level_vertices = observed_level_;
  s.prealign_level = prealign_level_;
  s.last_photometric = last_photometric_;
  s.consecutive_failures = consecutive_failures_;
  s.failures_total = failures_total_;
  s.recoveries = recoveries_;
  s.rejected_total = rejected_total_;
  s.rectification_information = rectification_.information();
  s.rectification_information_vector = rectification_.informationVector();
  s.rectification_pairs = rectification_.pairs();
  s.rectification = stereo_.rectification();
  s.rectification_set = stereo_.rectificationSet();
  if (prev_left_) s.previous_left = prev_left_->level(0).image;
  if (prev_right_) s.previous_right = prev_right_->level(0).image;
  s.previous_obstacles = prev_obstacles_;
  s.previous_moving = prev_moving_;
  s.carried_moving = carried_moving_;
  s.last_left = last_left_level0_;
  return s;
}

void IncrementalEstimator::restore(const EstimatorState& s) {
  auto fail = [](const std::string& why) { throw std::invalid_argument("saved estimator state: " + why); };
  const auto finite = [](const Eigen::Isometry3d& t) { return t.matrix().allFinite(); };
  if (!finite(s.ground_T_camera0) || !finite(s.ground_T_camera) || !finite(s.last_camera_T_ground) ||
      !s.velocity.allFinite() || !std::isfinite(s.last_stamp_s) || !std::isfinite(s.velocity_gap_s) ||
      !std::isfinite(s.residual_level_grey) || !std::isfinite(s.prealign_level) ||
      !std::isfinite(s.temporal_residual_level_grey) || !std::isfinite(s.observed_level_vertices))
    fail("a pose, the velocity, the stamp or a residual level is not finite");
  if (s.frame_counter < 0 || s.consecutive_failures < 0 || s.rectification_pairs < 0) fail("negative counter");
  const auto checkImage = [&](const cv::Mat& m, const char* name) {
    if (m.empty()) return;
    if (m.type() != CV_32FC1) fail(std::string(name) + " image is not single-channel float");
    if ((rig_.width > 0 && m.cols != rig_.width) || (rig_.height > 0 && m.rows != rig_.height)) {
      std::ostringstream os;
      os << name << " image is " << m.cols << "x" << m.rows << ", the calibration " << rig_.width << "x"
         << rig_.height;
      fail(os.str());
    }
  };
  checkImage(s.previous_left, "previous left");
  checkImage(s.previous_right, "previous right");
  checkImage(s.last_left, "last left");
  if (s.initialized && (s.previous_left.empty() || s.previous_right.empty()))
    fail("initialized without the previous images");
  if (s.previous_left.size() != s.previous_right.size()) fail("previous left and right images differ in size");
  std::unique_ptr<ImagePyramid> pl, pr;
  if (!s.previous_left.empty()) {
    // the saved level 0 is already pre-smoothed: rebuild the levels without smoothing it again
    pl = std::make_unique<ImagePyramid>(s.previous_left, stereo_.pyramidLevels(), ImagePyramid::ColorOrder::kBgr, 0.0);
    pr = std::make_unique<ImagePyramid>(s.previous_right, stereo_.pyramidLevels(), ImagePyramid::ColorOrder::kBgr, 0.0);
  }
  for (size_t l = 0; l < s.previous_obstacles.size(); ++l) {
    const cv::Mat& m = s.previous_obstacles[l];
    if (m.empty()) continue;
    if (m.type() != CV_8UC1 || !pl || static_cast<int>(l) >= pl->levels() ||
        m.size() != pl->level(static_cast<int>(l)).image.size())
      fail("obstacle mask of level " + std::to_string(l) + " does not fit the images");
  }
  // the moving-texture masks: none, or one for every pyramid level
  for (const auto* masks : {&s.previous_moving, &s.carried_moving}) {
    if (masks->empty()) continue;
    const char* what = masks == &s.previous_moving ? "previous moving-texture" : "carried moving-texture";
    if (!pl || static_cast<int>(masks->size()) != pl->levels())
      fail(std::string(what) + " masks: " + std::to_string(masks->size()) + " levels for " +
           std::to_string(pl ? pl->levels() : 0) + " image levels");
    for (size_t l = 0; l < masks->size(); ++l) {
      const cv::Mat& m = (*masks)[l];
      if (m.type() != CV_8UC1 || m.size() != pl->level(static_cast<int>(l)).image.size())
        fail(std::string(what) + " mask of level " + std::to_string(l) + " does not fit the images");
    }
  }
  initialized_ = s.initialized;
  frame_counter_ = s.frame_counter;
  ground_T_camera0_ = s.ground_T_camera0;
  ground_T_camera_ = s.ground_T_camera;
  predictor_.restore(s.last_camera_T_ground, s.last_stamp_s, s.velocity, s.velocity_gap_s, s.velocity_known);
  if (s.clock_rebased) predictor_.distrustLastStamp();
  residual_level_ = s.residual_level_grey;
  temporal_residual_level_ = s.temporal_residual_level_grey;
  observed_level_ = s.observed_level_vertices;
  prealign_level_ = s.prealign_level;
  last_photometric_ = s.last_photometric;
  consecutive_failures_ = s.consecutive_failures;
  failures_total_ = s.failures_total;
  recoveries_ = s.recoveries;
  rejected_total_ = s.rejected_total;
  rectification_.restore(s.rectification_information, s.rectification_information_vector, s.rectification_pairs);
  if (s.rectification_set) stereo_.setRectification(s.rectification);
  else stereo_.clearRectification();
  prev_left_ = std::move(pl);
  prev_right_ = std::move(pr);
  prev_obstacles_ = s.previous_obstacles;
  prev_moving_ = s.previous_moving;
  carried_moving_ = s.carried_moving;
  last_left_level0_ = s.last_left;
}

std::string IncrementalEstimator::checkImages(const ImagePyramid& left, const ImagePyramid& right) const {
  const IncrementalEstimatorOptions& o = options_;
  const char* names[2] = {"left", "right"};
  const ImagePyramid* p[2] = {&left, &right};
  for (int i = 0; i < 2; ++i) {
    const cv::Mat& img = p[i]->level(0).image;
    cv::Scalar mean, stddev;
    cv::meanStdDev(img, mean, stddev);
    std::ostringstream os;
    if (mean[0] < o.min_mean_grey) {
      os << names[i] << " image is black (mean " << mean[0] << " grey levels)";
      return os.str();
    }
    const double sat = cv::countNonZero(img >= static_cast<float>(o.stereo.aligner.saturated_level_grey)) /
                       static_cast<double>(img.total());
    if (sat > o.max_saturated_fraction) {
      os << names[i] << " image is saturated (" << static_cast<int>(100 * sat) << "% of pixels)";
      return os.str();
    }
    if (stddev[0] < o.min_std_grey) {
      os << names[i] << " image has no texture (standard deviation " << stddev[0] << " grey levels)";
      return os.str();
    }
  }
  if (!last_left_level0_.empty() && last_left_level0_.size() == left.level(0).image.size()) {
    cv::Mat diff;
    cv::absdiff(left.level(0).image, last_left_level0_, diff);
    if (cv::mean(diff)[0] < o.frozen_mean_abs_diff_grey) return "left image is identical to the previous one (frozen camera)";
  }
  return {};
}

cv::Mat IncrementalEstimator::surfaceDisparity(const Eigen::Isometry3d& ground_T_camera) const {
  if (!initialized_ || !prev_left_) throw std::logic_error("IncrementalEstimator::surfaceDisparity before initialization");
  const Eigen::Isometry3d camera_T_ground = ground_T_camera.inverse();
  const GroundGrid window = viewWindow(camera_T_ground);
  Eigen::VectorXd heights, info;
  map_.sample(window, &heights, &info);
  return stereo_.surfaceInverseDepth(*prev_left_, window, heights, camera_T_ground, 0) * rig_.disparityTimesDepth();
}

GroundGrid IncrementalEstimator::viewWindow(const Eigen::Isometry3d& camera_T_ground) const {
  return mapView().window(camera_T_ground);
}

MapView IncrementalEstimator::mapView() const {
  return MapView(rig_, options_.stereo, options_.max_init_std_m, options_.ground_plane, map_);
}

PoseSearchOptions IncrementalEstimator::poseSearchOptions() const {
  PoseSearchOptions p;
  p.aligner = options_.stereo.alignerOptions();
  p.search_level = options_.stereo.mesh_levels - 1;
  p.search_candidates = options_.search_candidates;
  p.prealign_level = options_.prealign_level;
  p.prealign_iterations = options_.prealign_iterations;
  p.prealign_screen_iterations = options_.prealign_screen_iterations;
  p.prealign_refine_iterations = options_.prealign_refine_iterations;
  p.hypothesis_accept_ratio = options_.hypothesis_accept_ratio;
  p.hypothesis_win_ratio = options_.hypothesis_win_ratio;
  p.nominal_frame_period_s = options_.nominal_frame_period_s;
  p.use_cross_temporal_pair = options_.use_cross_temporal_pair;
  return p;
}

Eigen::Isometry3d IncrementalEstimator::predict(double stamp_s) const { return predictor_.predict(stamp_s); }

FrameResult IncrementalEstimator::processFrame(const cv::Mat& left, const cv::Mat& right, double stamp_s,
                                               ImagePyramid::ColorOrder order) {
  const auto t0 = std::chrono::steady_clock::now();
  FrameResult res;
  res.frame_index = frame_counter_++;
  res.stamp_s = stamp_s;
  auto finish = [&](FrameResult& r) -> FrameResult {
    r.rectification = stereo_.rectification();
    r.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    r.camera0_T_camera = ground_T_camera0_.inverse() * r.ground_T_camera;
    return r;
  };
  auto reject = [&](const std::string& why) -> FrameResult {
    res.status = FrameStatus::kRejectedInput;
    res.message = why;
    res.ground_T_camera = initialized_ ? predict(stamp_s).inverse() : Eigen::Isometry3d::Identity();
    ++rejected_total_;
    return finish(res);
  };
  if (left.empty() || right.empty()) return reject("empty image");
  if (left.size() != right.size()) {
    std::ostringstream os;
    os << "left and right images differ in size (" << left.cols << "x" << left.rows << " vs " << right.cols << "x"
       << right.rows << ")";
    return reject(os.str());
  }
  if ((rig_.width > 0 && left.cols != rig_.width) || (rig_.height > 0 && left.rows != rig_.height)) {
    std::ostringstream os;
    os << "image size " << left.cols << "x" << left.rows << " does not match the calibration (" << rig_.width << "x"
       << rig_.height << ")";
    return reject(os.str());
  }
  if (!std::isfinite(stamp_s)) return reject("time stamp is not finite");
  if (initialized_ && stamp_s < predictor_.lastStamp()) return reject("time stamp goes backwards");
  std::unique_ptr<ImagePyramid> pl, pr;
  const auto t_pyr = std::chrono::steady_clock::now();
  {
    // the two pyramids side by side (the same images for any number of threads)
    std::string bad_image[2];
    auto build = [&](int i) {
      try {
        (i == 0 ? pl : pr) = std::make_unique<ImagePyramid>(stereo_.makePyramid(i == 0 ? left : right, order));
      } catch (const std::invalid_argument& e) {
        bad_image[i] = e.what();
      }
    };
    if (options_.stereo.aligner.num_threads > 1) {
      tbb::task_arena arena(2);
      arena.execute([&] { tbb::parallel_for(0, 2, build); });
    } else {
      build(0);
      build(1);
    }
    for (const std::string& why : bad_image)
      if (!why.empty()) return reject(why);
  }
  res.pyramid_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_pyr).count();
  const std::string bad = checkImages(*pl, *pr);
  if (!bad.empty()) return reject(bad);
  last_left_level0_ = pl->level(0).image;

  if (!initialized_) {
    const StereoResult sr = stereo_.estimate(*pl, *pr);
    if (!sr.ok) {
      res.status = FrameStatus::kFailed;
      res.message = "initialization (stereo mode): " + sr.message;
      ++failures_total_;
      return finish(res);
    }
    addPairCheck(sr.pair_check);
    ground_T_camera0_ = sr.ground_T_camera;
    ground_T_camera_ = sr.ground_T_camera;
    std::vector<uint8_t> update(static_cast<size_t>(sr.grid.vertexCount()));
    for (int v = 0; v < sr.grid.vertexCount(); ++v) update[static_cast<size_t>(v)] = std::isfinite(sr.heights[v]);
    map_.fuse(sr.grid, sr.heights, Eigen::VectorXd::Zero(sr.grid.vertexCount()), sr.information, update, res.frame_index);
    map_.updateObstacles(sr.grid, sr.obstacle_evidence.hit, sr.obstacle_evidence.ground, sr.obstacle_evidence.height,
                         res.frame_index);
    res.fused_vertices = static_cast<int>(std::count(update.begin(), update.end(), 1));
    initialized_ = true;
    predictor_.setPose(sr.ground_T_camera.inverse(), stamp_s);
    residual_level_ = sr.median_abs_residual_grey;
    prealign_level_ = temporal_residual_level_ = 0.0;
    observed_level_ = res.fused_vertices;
    prev_obstacles_ = sr.obstacles.excluded;
    prev_moving_.clear();
    carried_moving_.clear();
    advance(sr.ground_T_camera, stamp_s, pl, pr, {sr.photometric});
    res.status = FrameStatus::kInitialized;
    res.ground_T_camera = sr.ground_T_camera;
    res.photometric = last_photometric_;
    res.window = sr.grid;
    res.median_abs_residual_grey = sr.median_abs_residual_grey;
    return finish(res);
  }

  // ---- incremental step
  if (consecutive_failures_ >= options_.reinit_after_failures) return finish(recoverFrame(*pl, *pr, stamp_s, &res, pl, pr));
  return finish(trackFrame(stamp_s, &res, pl, pr));
}

double IncrementalEstimatorOptions::maxPrealignShiftM(double gap_s) const {
  if (!(max_acceleration_mps2 > 0.0)) return std::numeric_limits<double>::infinity();
  // never tighter than one nominal frame period's: a jittered or wrong stamp a millisecond after
  // the last one must not reject a sound alignment
  const double t = std::max(gap_s, nominal_frame_period_s);
  return max_acceleration_mps2 * t * t;
}

int IncrementalEstimator::effectiveTemporalFinestLevel(int image_width_px) const {
  int level = options_.temporal_finest_level;
  while (level > 0 && (image_width_px >> level) < options_.min_temporal_width_px) --level;
  return level;
}

FrameResult& IncrementalEstimator::trackFrame(double stamp_s, FrameResult* out, std::unique_ptr<ImagePyramid>& pl,
                                              std::unique_ptr<ImagePyramid>& pr,
                                              const Eigen::Isometry3d* relocalize_start) {
  FrameResult& res = *out;
  const StereoEstimatorOptions& so = options_.stereo;
  const double dt = predictor_.gap(stamp_s);
  // The ground's outline against a blank sky moves with the viewpoint, not with the ground
  // (SkylineMask): every comparison with the previous images skips it, the search included.
  // (only the levels the temporal pairs use: the finest temporal level and coarser)
  std::vector<cv::Mat> temporal_skipped = skyline_.compute(*pl, effectiveTemporalFinestLevel(pl->level(0).image.cols));
  // Starting poses: the predictor's hypotheses, or the best of its search grid without a velocity.
  const MapView view = mapView();
  const Eigen::Isometry3d prev_c_T_g = ground_T_camera_.inverse();
  PoseSearchContext context;
  context.rig = &rig_;
  context.stereo = &stereo_;
  context.map = &view;
  context.predictor = &predictor_;
  context.prev_left = prev_left_.get();
  context.prev_right = prev_right_.get();
  context.prev_camera_T_ground = prev_c_T_g;
  const PoseSearch search(poseSearchOptions(), context);
  PrealignRequest request;
  request.left = pl.get();
  request.right = pr.get();
  if (relocalize_start) {
    request.starts = {*relocalize_start};
  } else if (predictor_.velocityKnown()) {
    request.starts = predictor_.hypotheses(stamp_s);
  } else {
    const StereoPairCheck pair = stereo_.checkPair(*pl, *pr);
    if (consecutive_failures_ > 0) {
      // Placed without a velocity after a failure: the pair must show ground near the mounted
      // attitude (not the sky, not a pair turned over), or the search may fit it anywhere.
      const DisparityPlane ground = stereo_.groundPlane(*pl, *pr, pair);
      if (!ground.ok) return failFrame(stamp_s, "no ground in view near the mounted attitude: " + ground.message, &res);
    }
    request.starts = search.rankedStarts(*pl, stamp_s, temporal_skipped);
    Eigen::Isometry3d anchored;
    if (view.groundAnchoredPose(pair, request.starts.front(), &anchored)) {
      request.starts.insert(request.starts.begin() + 1, anchored);
      request.anchored_index = 1;
    }
    for (const Eigen::Isometry3d& p : predictor_.attitudeSteps(request.starts.front())) request.starts.push_back(p);
  }
  const Eigen::Isometry3d predicted = request.starts.front();  // camera_T_ground

  const AlignerTarget stereo_t = stereo_.stereoTarget(*pr, stereo_.rectification());
  AlignerTarget prev_l;
  prev_l.pyramid = prev_left_.get();
  prev_l.rig_fixed = false;
  prev_l.target_T_ground = prev_c_T_g;
  prev_l.checkerboard = options_.temporal_checkerboard;
  if (options_.exclude_previous_obstacles && !prev_obstacles_.empty()) prev_l.excluded = &prev_obstacles_;
  AlignerTarget prev_r = prev_l;
  prev_r.pyramid = prev_right_.get();
  prev_r.target_T_ground = stereo_.rightTLeft(stereo_.rectification()) * prev_c_T_g;
  prev_r.row_shift_px = stereo_t.row_shift_px;
  prev_r.excluded = nullptr;  // the previous obstacle mask is in the previous LEFT image
  // The temporal pairs skip the outline (above), the texture that moved with the vehicle in the
  // last two frames (carry_moving_texture) and, after the test below, this frame's moving texture.
  if (options_.carry_moving_texture && carried_moving_.size() == static_cast<size_t>(pl->levels())) {
    addMasks(carried_moving_, *pl, &temporal_skipped);
    const size_t tl = static_cast<size_t>(std::min(options_.temporal_consistency.level, pl->levels() - 1));
    res.carried_moving_pixels = cv::countNonZero(carried_moving_[tl]);
  }
  if (!temporal_skipped.empty()) {
    prev_l.reference_excluded = &temporal_skipped;
    prev_r.reference_excluded = &temporal_skipped;
  }
  SurfaceAlignerOptions ao = so.alignerOptions();
  ao.estimate_motion = true;

  // ---- 1. motion only, at a coarse level, from the starting poses (PoseSearch::prealign())
  const auto t_pre = std::chrono::steady_clock::now();
  request.targets = {stereo_t, prev_l, prev_r};
  request.gap_s = dt;
  request.max_shift_m = options_.maxPrealignShiftM(dt);
  request.usual_cost = prealign_level_;
  Prealignment pre = search.prealign(std::move(request));
  res.prealign_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_pre).count();
  res.reports.insert(res.reports.end(), pre.reports.begin(), pre.reports.end());
  res.prealign_cost = pre.cost;
  res.prealign_shift_m = pre.shift_m;
  res.prealign_rejected = pre.rejected;
  res.prealign_discarded = pre.discarded;
  SurfaceState state;
  state.camera_T_ground = pre.camera_T_ground;
  state.photometric = pre.photometric;
  GroundGrid window = pre.window;
  Eigen::VectorXd heights = std::move(pre.heights), info = std::move(pre.information);
  const GroundGrid aligned_window = view.window(state.camera_T_ground);
  if (!aligned_window.sameLayout(window)) {
    window = aligned_window;
    view.initialHeights(window, state.camera_T_ground, &heights, &info);
  }
  state.heights = heights;  // (the starts may have moved the window: these match it)
  res.window = window;
  HeightPrior prior;
  prior.mean = heights;
  prior.information = info * options_.prior_weight;

  // ---- 2. occlusion reasoning at the aligned pose
  const auto t_obst = std::chrono::steady_clock::now();
  Eigen::VectorXd far_ceilings;  // bounds on the ground from the rays that saw past the surface
  ObstacleMask obstacles =
      stereo_.detectObstacles(*pl, *pr, window, heights, state.camera_T_ground, state.photometric[0]);
  {
    // Ground the surface does not hold: seen past it (a crest's far side: its unknown vertices start
    // at its points, vertices its rays pass under at the ray; FarGroundSeeds), or rising out of it
    // (a hill ahead that the upright test took: its unknown vertices start on its points' planes;
    // RisingGroundSeeds). The test then runs again on that surface.
    Eigen::VectorXd starts;
    bool converge = false;  // the band between far seeds and the known ground: converged extension
    if (options_.far_seeds.enabled && obstacles.far_pixels >= options_.far_seeds.min_far_pixels) {
      const std::vector<Eigen::Vector3d> far = obstacles.farPoints(rig_, state.camera_T_ground.inverse());
      const FarGroundStarts fs = FarGroundSeeds(options_.far_seeds)
                                     .starts(window, heights, info, state.camera_T_ground.inverse().translation(), far);
      res.far_seeded_vertices = fs.seeded_vertices;
      res.far_carved_vertices = fs.carved_vertices;
      far_ceilings = fs.ceilings;
      starts = fs.heights;
      converge = fs.seeded_vertices > 0;
    }
    if (options_.rising_seeds.enabled && obstacles.pixels > 0) {
      const Eigen::VectorXd rs = RisingGroundSeeds(options_.rising_seeds)
                                     .seeds(window, heights, info, state.camera_T_ground.inverse().translation(),
                                            obstacles.uprightPoints(rig_, state.camera_T_ground.inverse()));
      if (starts.size() == 0) starts = Eigen::VectorXd::Constant(rs.size(), std::numeric_limits<double>::quiet_NaN());
      for (int v = 0; v < window.vertexCount(); ++v) {
        if (!std::isfinite(rs[v])) continue;
        ++res.rising_seeded_vertices;
        if (!std::isfinite(starts[v])) starts[v] = rs[v];  // the far side's starts first
      }
    }
    if (res.far_seeded_vertices > 0 || res.rising_seeded_vertices > 0) {
      view.initialHeights(window, state.camera_T_ground, &heights, &info, &starts, converge);
      state.heights = heights;
      prior.mean = heights;
      prior.information = info * options_.prior_weight;
      obstacles = stereo_.detectObstacles(*pl, *pr, window, heights, state.camera_T_ground, state.photometric[0]);
    }
  }
  res.obstacle_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_obst).count();
  res.obstacle_pixels = obstacles.pixels;
  res.far_pixels = obstacles.far_pixels;

  // ---- 3. heights, motion and photometry jointly, coarse to fine (alignJointLevels())
  const auto t_joint = std::chrono::steady_clock::now();
  TemporalInconsistency moving;  // ground whose texture moved (the temporal pairs skip it)
  const AlignmentReport last = alignJointLevels(*pl, *pr, window, obstacles, prior, {stereo_t, prev_l, prev_r},
                                                &temporal_skipped, ao, &state, &moving, &res, predicted);
  res.joint_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_joint).count();
  std::copy_n(state.photometric.begin(), 3, res.photometric.begin());
  res.median_abs_residual_grey = last.median_abs_residual_grey;
  res.valid_pixels = last.valid_pixels;

  // ---- 4. plausibility
  const Vector6d step = Se3::log(state.camera_T_ground * ground_T_camera_);  // prev camera -> current
  const int samples = last.valid_pixels + last.outside_pixels;
  int jumps = 0, well_known = 0;
  const std::vector<uint8_t> update =
      observedVertices(window, state.heights, state.camera_T_ground.inverse().translation(), last, prior.mean, info,
                       &well_known, &jumps);
  TrackingEvidence ev;
  ev.degenerate = last.degenerate;
  ev.finite = state.camera_T_ground.matrix().allFinite() && state.heights.allFinite();
  ev.step = step;
  ev.dt_s = dt;
  ev.samples = samples;
  ev.outside = last.outside_pixels;
  ev.well_known = well_known;
  ev.jumps = jumps;
  ev.median_residual_grey = last.median_abs_residual_grey;
  ev.usual_residual_grey = residual_level_;
  ev.temporal_residual_grey = res.temporal_residual_grey;
  ev.usual_temporal_residual_grey = temporal_residual_level_;
  // the level is learnt at about the last tracked step's gap (none yet: the nominal frame period)
  const double usual_gap_s = predictor_.lastGap() > 0.0 ? predictor_.lastGap() : options_.nominal_frame_period_s;
  ev.temporal_gap_ratio = std::max(1.0, dt / usual_gap_s);
  ev.observed_vertices = static_cast<int>(std::count(update.begin(), update.end(), 1));
  ev.usual_observed_vertices = observed_level_;
  std::string failure = check_.failure(ev);
  if (!failure.empty()) {
    if (!std::isfinite(res.prealign_cost)) {
      // what the pre-alignment found: the joint levels started from the prediction
      failure += res.prealign_rejected ? " (the pre-alignment moved beyond the acceleration bound)"
                 : res.prealign_discarded > 0
                     ? " (no pre-alignment start aligned within the acceleration bound: " +
                           std::to_string(res.prealign_discarded) + " ended beyond it)"
                     : " (no pre-alignment start aligned)";
    }
    return failFrame(stamp_s, failure, &res);
  }

  // ---- 5. fuse, advance
  const Eigen::VectorXd fused_prior_info =
      options_.use_map_prior ? prior.information : Eigen::VectorXd::Zero(window.vertexCount());
  map_.fuse(window, state.heights, fused_prior_info, last.vertex_information, update, res.frame_index);
  if (far_ceilings.size() == window.vertexCount()) {
    // What the map holds above a far ray and this frame did not measure again is refuted: published
    // as unknown. The estimator keeps starting from it (forgetting it moved the tracking both ways,
    // docs/results.md "Map heights the far rays refute").
    res.far_refuted_vertices =
        map_.markRefuted(window, far_ceilings, options_.far_seeds.ceiling_margin_m, update);
  }
  const Eigen::Vector3d camera_position = state.camera_T_ground.inverse().translation();
  const ObstacleEvidence oe = ObstacleDetector::evidence(
      window, state.heights, last.vertex_pixels, last.vertex_excluded_pixels,
      obstacles.groundPoints(rig_, state.camera_T_ground.inverse()), so.hidden_pixel_ratio, so.min_ground_pixels,
      so.obstacles.min_obstacle_height_m, so.obstacles.hidden_body_depth_m, 2,
      so.obstacles.hidden_body_along_ray ? &camera_position : nullptr);
  map_.updateObstacles(window, oe.hit, oe.ground, oe.height, res.frame_index);

  res.obstacle_vertices = static_cast<int>(std::count(oe.hit.begin(), oe.hit.end(), 1));
  res.fused_vertices = static_cast<int>(std::count(update.begin(), update.end(), 1));
  if (rectificationDue(res.frame_index)) addPairCheck(stereo_.checkPair(*pl, *pr));
  predictor_.update(state.camera_T_ground, stamp_s);
  if (std::isfinite(res.prealign_cost)) {
    prealign_level_ = prealign_level_ > 0.0 ? 0.8 * prealign_level_ + 0.2 * res.prealign_cost : res.prealign_cost;
  }
  observed_level_ = observed_level_ > 0.0 ? 0.8 * observed_level_ + 0.2 * ev.observed_vertices : ev.observed_vertices;
  residual_level_ = residual_level_ > 0.0 ? 0.8 * residual_level_ + 0.2 * last.median_abs_residual_grey
                                          : last.median_abs_residual_grey;
  if (res.temporal_residual_grey > 0.0) {  // 0: not measured
    const double at_usual_gap = res.temporal_residual_grey / ev.temporal_gap_ratio;  // (as the check scales it)
    temporal_residual_level_ =
        temporal_residual_level_ > 0.0 ? 0.8 * temporal_residual_level_ + 0.2 * at_usual_gap : at_usual_gap;
  }
  prev_obstacles_ = obstacles.excluded;
  // What this frame and the one before both flagged moved with the vehicle (every level of both
  // sets present and alike in size, else nothing is carried).
  carried_moving_.clear();
  bool alike = !moving.masks.empty() && prev_moving_.size() == moving.masks.size();
  for (size_t ml = 0; alike && ml < moving.masks.size(); ++ml)
    alike = !moving.masks[ml].empty() && moving.masks[ml].size() == prev_moving_[ml].size() &&
            moving.masks[ml].type() == prev_moving_[ml].type();
  if (alike) {
    bool any = false;
    for (size_t ml = 0; ml < moving.masks.size(); ++ml) {
      carried_moving_.push_back(prev_moving_[ml] & moving.masks[ml]);
      any = any || cv::countNonZero(carried_moving_.back()) > 0;
    }
    if (!any) carried_moving_.clear();
  }
  prev_moving_ = moving.masks;
  advance(state.camera_T_ground.inverse(), stamp_s, pl, pr, state.photometric);
  res.status = FrameStatus::kTracked;
  res.ground_T_camera = ground_T_camera_;
  return res;
}

// 3. Heights, motion and photometry jointly, coarse to fine, from the pre-aligned `state`; the
// temporal-consistency test after the first level with motion (its moving texture is added to
// what the temporal pairs skip, and that level is estimated once more).
AlignmentReport IncrementalEstimator::alignJointLevels(const ImagePyramid& pl, const ImagePyramid& pr,
                                                       const GroundGrid& window, const ObstacleMask& obstacles,
                                                       const HeightPrior& prior, std::array<AlignerTarget, 3> targets,
                                                       std::vector<cv::Mat>* temporal_skipped_io, SurfaceAlignerOptions ao,
                                                       SurfaceState* state_io, TemporalInconsistency* moving_out,
                                                       FrameResult* res_io, const Eigen::Isometry3d& predicted) {
  std::vector<cv::Mat>& temporal_skipped = *temporal_skipped_io;
  SurfaceState& state = *state_io;
  TemporalInconsistency& moving = *moving_out;
  FrameResult& res = *res_io;
  const StereoEstimatorOptions& so = options_.stereo;
  SurfaceAlignerOptions ao_static = ao;
  ao_static.estimate_motion = false;
  ao.max_iterations = ao_static.max_iterations = options_.fine_iterations;
  SurfaceAlignerOptions ao_coarse = ao, ao_static_coarse = ao_static;
  ao.final_undamped_step = options_.final_undamped_step >= 2;
  ao_static.final_undamped_step = options_.final_undamped_step == 1 || options_.final_undamped_step == 2;
  ao_coarse.max_iterations = ao_static_coarse.max_iterations = options_.iterations_per_level;
  if (options_.motion_max_depth_m > 0.0) {
    ao.max_depth_m = std::min(ao.max_depth_m, options_.motion_max_depth_m);
    ao_coarse.max_depth_m = std::min(ao_coarse.max_depth_m, options_.motion_max_depth_m);
  }
  if (options_.stereo_fine_iterations > 0) ao_static.max_iterations = options_.stereo_fine_iterations;
  SurfaceAlignerOptions ao_repeat = ao;
  if (options_.repeat_iterations > 0) ao_repeat.max_iterations = options_.repeat_iterations;
  const SurfaceAligner aligner_motion(ao), aligner_static(ao_static), aligner_repeat(ao_repeat);
  const SurfaceAligner aligner_motion_coarse(ao_coarse), aligner_static_coarse(ao_static_coarse);
  AlignmentProblem prob;
  prob.reference = &pl;
  prob.rig = &rig_;
  prob.grid = &window;
  prob.prior = options_.use_map_prior ? &prior : nullptr;
  prob.excluded = &obstacles.excluded;
  AlignmentReport last;
  bool consistency_checked = false;
  // Small images: the temporal pairs (and the motion) go down to a level at least
  // min_temporal_width_px wide, finer than temporal_finest_level when needed.
  const int temporal_finest = effectiveTemporalFinestLevel(pl.level(0).image.cols);
  res.temporal_finest_level = temporal_finest;
  bool second_pass = false;  // the finest temporal level once more, after the consistency test
  bool moving_texture = false;  // ... which took moving texture out of the temporal pairs
  for (int l = std::min(so.mesh_levels, options_.tracking_levels) - 1; l >= 0; --l) {
    prob.level = l;
    const bool temporal = l >= temporal_finest;
    // The photometric state is per target; keep the three slots and pass the used subset.
    SurfaceState level_state = state;
    const std::vector<int> slots = pairSlots(temporal, options_.use_cross_temporal_pair);
    prob.targets.clear();
    level_state.photometric.clear();
    for (int sl : slots) {
      prob.targets.push_back(targets[static_cast<size_t>(sl)]);
      level_state.photometric.push_back(state.photometric[static_cast<size_t>(sl)]);
    }
    Eigen::SparseMatrix<double, Eigen::RowMajor> basis;
    stereo_.levelBasis(window, l, state.heights, state.camera_T_ground, &basis, &prob.update_weight);
    prob.basis = basis.size() > 0 ? &basis : nullptr;
    // Once per frame: at the first pass of the finest level with motion (a second pass after the
    // consistency test changes the motion by millimetres; the information hardly).
    prob.want_motion_information =
        options_.motion_information && temporal && l == temporal_finest && !second_pass;
    const SurfaceAligner& aligner = l >= 2 ? (temporal ? aligner_motion_coarse : aligner_static_coarse)
                                           : (temporal ? (second_pass ? aligner_repeat : aligner_motion) : aligner_static);
    // The second pass after the moving-texture test: the first estimated the motion with that
    // texture in and was pulled by it (a car ahead and its shadow, toward standing still); the
    // prediction did not look at this frame's images. Without the texture, the prediction is the
    // start when its cost per sample is clearly lower (hypothesis_win_ratio, as another
    // pre-alignment start must beat the prediction). Not after the visibility test alone: ground
    // the previous camera did not see does not move, and starting from the prediction there cost
    // the rolling scene's attitude (docs/results.md, "The second pass from the prediction").
    const bool offer_prediction =
        temporal && l == temporal_finest && second_pass && moving_texture && options_.repeat_from_prediction;
    prob.alternative_start = offer_prediction ? &predicted : nullptr;
    prob.alternative_win_ratio = options_.hypothesis_win_ratio;
    last = aligner.align(prob, level_state);
    if (offer_prediction) res.repeat_from_prediction = last.started_from_alternative;
    res.reports.push_back(last);
    if (prob.want_motion_information) res.motion_information = last.motion_information;
    if (temporal && l == temporal_finest && last.target_median_abs_residual_grey.size() >= 2) {
      res.stereo_residual_grey = last.target_median_abs_residual_grey[0];
      res.temporal_residual_grey = last.target_median_abs_residual_grey[1];
    }
    state.camera_T_ground = level_state.camera_T_ground;
    state.heights = level_state.heights;
    for (size_t i = 0; i < slots.size(); ++i) state.photometric[static_cast<size_t>(slots[i])] = level_state.photometric[i];
    if (last.degenerate) break;
    bool repeat = false;  // the finest temporal level once more, without what the tests below found
    if (temporal && !consistency_checked && options_.temporal_consistency.enabled) {
      // Ground whose texture moved (a moving shadow): flagged after the coarsest joint level, so
      // that the finer temporal levels skip it. When this already was the finest temporal level
      // (the default at KITTI resolution: levels 1 and 0, temporal down to 1), it is estimated
      // once more.
      // tracking_levels 3 tests after level 2 instead of repeating level 1: ~7 % faster per frame
      // and better on the crest, off-road, bounce and traffic scenes, but the shadows scene's
      // heights 2x worse (docs/results.md, "Tried"), so it is not the default.
      consistency_checked = true;
      const int tl = std::min(options_.temporal_consistency.level, pl.levels() - 1);
      const cv::Mat rho = stereo_.surfaceInverseDepth(pl, window, state.heights, state.camera_T_ground, tl);
      const cv::Mat ex = static_cast<int>(obstacles.excluded.size()) > tl ? obstacles.excluded[static_cast<size_t>(tl)] : cv::Mat();
      moving = TemporalConsistency(options_.temporal_consistency)
                   .detect(pl, pr, *prev_left_, rig_, rho, ex, ground_T_camera_.inverse() * state.camera_T_ground.inverse(),
                           state.photometric[0], state.photometric[1], stereo_.rectification());
      res.moving_pixels = moving.pixels;
      if (!moving.masks.empty()) {
        addMasks(moving.masks, pl, &temporal_skipped);
        targets[1].reference_excluded = &temporal_skipped;
        targets[2].reference_excluded = &temporal_skipped;
        repeat = true;
        moving_texture = true;
      }
    }
    if (temporal && l == temporal_finest && !second_pass && options_.temporal_visibility.enabled && prev_left_) {
      // Ground the previous camera did not see (TemporalVisibility), at this pass's pose and heights.
      const cv::Mat rho = stereo_.surfaceInverseDepth(pl, window, state.heights, state.camera_T_ground, l);
      const Eigen::Isometry3d prev_c_T_g = ground_T_camera_.inverse();
      const cv::Mat rho_prev = stereo_.surfaceInverseDepth(*prev_left_, window, state.heights, prev_c_T_g, l);
      const cv::Mat hidden = TemporalVisibility(options_.temporal_visibility)
                                 .hidden(rho, rho_prev, rig_.atLevel(l), prev_c_T_g * state.camera_T_ground.inverse());
      res.hidden_pixels = cv::countNonZero(hidden);
      if (res.hidden_pixels > 0) {
        addMasks(pl.maskOnEveryLevel(hidden, l), pl, &temporal_skipped);
        targets[1].reference_excluded = &temporal_skipped;
        targets[2].reference_excluded = &temporal_skipped;
        // Enough of it to matter: this level once more (a few pixels behind small bumps ride along
        // with the consistency test's repeat, if any).
        if (res.hidden_pixels > options_.temporal_visibility.min_repeat_share * last.valid_pixels) repeat = true;
      }
    }
    if (repeat && l == temporal_finest && !second_pass) {
      ++l;  // this level once more
      second_pass = true;
    }
  }
  return last;
}

// The vertices whose heights this frame measured (fused), and among the well-known ones
// (information > 1e3, std below ~3 cm) those that jumped by more than check.max_height_jump_m.
std::vector<uint8_t> IncrementalEstimator::observedVertices(const GroundGrid& window, const Eigen::VectorXd& heights,
                                                            const Eigen::Vector3d& camera_position,
                                                            const AlignmentReport& report,
                                                            const Eigen::VectorXd& prior_mean,
                                                            const Eigen::VectorXd& info, int* well_known,
                                                            int* jumps) const {
  const StereoEstimatorOptions& so = options_.stereo;
  std::vector<uint8_t> update(static_cast<size_t>(window.vertexCount()), 0);
  // Seen along its rays (the mesh draped over ground hidden behind a rail, the back of a crest):
  // its pixels do not measure its height.
  const Eigen::VectorXd incidence = so.min_incidence_ratio > 0.0
                                        ? SurfaceIncidence::ratios(window, heights, camera_position)
                                        : Eigen::VectorXd();
  for (int v = 0; v < window.vertexCount(); ++v) {
    if (report.vertex_pixels.size() == 0 || report.vertex_pixels[v] == 0 || !std::isfinite(heights[v])) continue;
    // Too few pixels, or too few with texture (sky behind a crest, glare): no height measurement.
    // (The textured pixels are a subset of the vertex's pixels.)
    if (report.vertex_textured_pixels[v] < so.min_ground_pixels) continue;
    // Seen mostly through obstacle pixels: the ground there is hidden, not observed.
    if (report.vertex_excluded_pixels[v] > so.hidden_pixel_ratio * report.vertex_pixels[v]) continue;
    if (incidence.size() > 0 && incidence[v] < so.min_incidence_ratio) continue;
    update[static_cast<size_t>(v)] = 1;
    if (info[v] > 1e3) {  // std below ~3 cm
      ++*well_known;
      if (std::abs(heights[v] - prior_mean[v]) > options_.check.max_height_jump_m) ++*jumps;
    }
  }
  return update;
}

FrameResult& IncrementalEstimator::failFrame(double stamp_s, const std::string& why, FrameResult* out) {
  ++consecutive_failures_;
  ++failures_total_;
  predictor_.forgetVelocity();
  out->status = FrameStatus::kFailed;
  out->message = why;
  // the pose moves on at the last velocity (the estimate is not trusted)
  out->ground_T_camera = predictor_.coast(stamp_s).inverse();
  return *out;
}

void IncrementalEstimator::advance(const Eigen::Isometry3d& ground_T_camera, double stamp_s,
                                   std::unique_ptr<ImagePyramid>& pl, std::unique_ptr<ImagePyramid>& pr,
                                   const std::vector<PhotometricParams>& photometric) {
  ground_T_camera_ = ground_T_camera;
  prev_left_ = std::move(pl);
  prev_right_ = std::move(pr);
  for (size_t j = 0; j < 3 && j < photometric.size(); ++j) last_photometric_[j] = photometric[j];
  consecutive_failures_ = 0;
  const Eigen::Vector3d pos = ground_T_camera.translation();
  map_.evictFarFrom(pos.x(), pos.y());
}

FrameResult& IncrementalEstimator::recoverFrame(const ImagePyramid& left, const ImagePyramid& right, double stamp_s,
                                                FrameResult* out, std::unique_ptr<ImagePyramid>& pl,
                                                std::unique_ptr<ImagePyramid>& pr) {
  // Re-initialization from the stereo pair: the stereo mode measures the surface and the camera's
  // height, pitch and roll relative to the ground in front of it; x, y and heading come from the
  // prediction (they drift, and that is counted). The camera is placed against the map's local
  // plane there (groundAnchoredPose: a slope stays a slope), else on a level plane at the map's
  // height under it.
  FrameResult& res = *out;
  const Eigen::Isometry3d predicted = predictor_.coast(stamp_s);  // the velocity is not trusted, but the best guess
  const StereoResult sr = stereo_.estimate(left, right);
  if (!sr.ok) {
    ++failures_total_;
    res.status = FrameStatus::kFailed;
    res.message = "re-initialization failed: " + sr.message;
    res.ground_T_camera = predicted.inverse();
    return res;
  }
  const Eigen::Isometry3d g_T_c_pred = predicted.inverse();
  // The local ground frame G' of the stereo result placed in the map: its origin under the
  // predicted camera at the map's ground level there, its x axis along the predicted heading.
  Eigen::Vector3d fwd = g_T_c_pred.linear().col(2);
  fwd.z() = 0.0;
  if (fwd.norm() < 1e-6) fwd = Eigen::Vector3d::UnitX();
  fwd.normalize();
  double ground_z = g_T_c_pred.translation().z() - options_.stereo.nominal_height_m;
  {
    const GroundGrid local = GroundGrid::covering(g_T_c_pred.translation().x() - 3.0, g_T_c_pred.translation().x() + 3.0,
                                                  g_T_c_pred.translation().y() - 3.0, g_T_c_pred.translation().y() + 3.0,
                                                  options_.stereo.grid_resolution_m);
    Eigen::VectorXd h, info;
    map_.sample(local, &h, &info);
    std::vector<double> known;
    for (int v = 0; v < h.size(); ++v)
      if (std::isfinite(h[v])) known.push_back(h[v]);
    if (known.size() > 5) {
      std::nth_element(known.begin(), known.begin() + static_cast<std::ptrdiff_t>(known.size() / 2), known.end());
      ground_z = known[known.size() / 2];
    }
  }
  Eigen::Isometry3d g_T_local = Eigen::Isometry3d::Identity();
  g_T_local.linear().col(0) = fwd;
  g_T_local.linear().col(1) = Eigen::Vector3d::UnitZ().cross(fwd);
  g_T_local.linear().col(2) = Eigen::Vector3d::UnitZ();
  g_T_local.translation() = Eigen::Vector3d(g_T_c_pred.translation().x(), g_T_c_pred.translation().y(), ground_z);
  Eigen::Isometry3d anchored;
  if (mapView().groundAnchoredPose(sr.pair_check, predicted, &anchored)) g_T_local = anchored.inverse() * sr.ground_T_camera.inverse();
  const Eigen::Isometry3d ground_T_camera = g_T_local * sr.ground_T_camera;
  const int failures = consecutive_failures_;
  std::string relocalization;
  if (options_.relocalize_against_map && prev_left_ && prev_right_) {
    // Re-localization: the frame tracked from that pose against the map and the last tracked
    // frame's images (still held: failures do not advance), as any other; on success it is the result.
    const FrameResult before = res;
    const int failures_total = failures_total_;
    const Eigen::Isometry3d start = ground_T_camera.inverse();
    trackFrame(stamp_s, &res, pl, pr, &start);
    if (res.status == FrameStatus::kTracked) {
      ++recoveries_;
      res.status = FrameStatus::kRecovered;
      res.message = "re-localized against the map after " + std::to_string(failures) + " failures";
      return res;
    }
    relocalization = res.message;
    res = before;
    consecutive_failures_ = failures;
    failures_total_ = failures_total;
  }
  // Resample the stereo surface on the map's lattice.
  const GroundGrid window = viewWindow(ground_T_camera.inverse());
  Eigen::VectorXd heights(window.vertexCount()), data_info = Eigen::VectorXd::Zero(window.vertexCount());
  std::vector<uint8_t> update(static_cast<size_t>(window.vertexCount()), 0);
  const Eigen::Isometry3d local_T_g = g_T_local.inverse();
  for (int v = 0; v < window.vertexCount(); ++v) {
    const Eigen::Vector2d xy = window.position(v);
    Eigen::Vector3d p = local_T_g * Eigen::Vector3d(xy.x(), xy.y(), ground_z);
    const double zl = sr.grid.interpolate(sr.heights, p.x(), p.y());
    heights[v] = std::numeric_limits<double>::quiet_NaN();
    if (!std::isfinite(zl)) continue;
    p.z() = zl;
    heights[v] = (g_T_local * p).z();
    data_info[v] = std::max(0.0, sr.grid.interpolate(sr.information, p.x(), p.y()));
    update[static_cast<size_t>(v)] = 1;
  }
  map_.fuse(window, heights, Eigen::VectorXd::Zero(window.vertexCount()), data_info, update, res.frame_index);
  res.fused_vertices = static_cast<int>(std::count(update.begin(), update.end(), 1));
  res.window = window;
  res.photometric = {sr.photometric, PhotometricParams(), PhotometricParams()};
  res.median_abs_residual_grey = sr.median_abs_residual_grey;
  ++recoveries_;
  res.status = FrameStatus::kRecovered;
  res.message = "re-initialized from the stereo pair after " + std::to_string(failures) + " failures";
  if (!relocalization.empty()) res.message += " (re-localization against the map: " + relocalization + ")";
  predictor_.setPose(ground_T_camera.inverse(), stamp_s);
  residual_level_ = sr.median_abs_residual_grey;
  observed_level_ = res.fused_vertices;
  temporal_residual_level_ = 0.0;  // the scene may have changed since the failures: learnt again
  prev_obstacles_ = sr.obstacles.excluded;
  prev_moving_.clear();
  carried_moving_.clear();
  advance(ground_T_camera, stamp_s, pl, pr, {sr.photometric});
  res.ground_T_camera = ground_T_camera;
  return res;
}

}  // namespace stereo_ground_dem
