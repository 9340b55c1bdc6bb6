#pragma once
/// \file IncrementalEstimator.hpp
/// Incremental mode (METHOD.md section 6, the paper's section 3): per stereo frame k, with the
/// current left image L_k as reference and the pairs (L_k, R_k), (L_k, L_k-1), (L_k, R_k-1), jointly
/// estimate the 6-DoF pose of frame k, the heights of the visible vertices and gain/bias of each
/// pair, coarse to fine, then fuse the heights into the ElevationMap.
///
/// Frame 0 runs the stereo mode, which defines the ground frame. Later frames start from a
/// constant-velocity prediction (scaled by the time since the last good frame, so dropped frames
/// are bridged), take known heights from the map (unknown ones by extending the surface with a
/// plane fitted to the known ones) and use the map as a prior. A frame whose estimate is
/// implausible is not fused; after `reinit_after_failures` failures in a row the frame is tracked
/// against the map from the stereo pair's attitude at the predicted pose (re-localization), or,
/// when that fails too, the surface is re-initialised from the stereo pair alone there.

#include <array>
#include <limits>
#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "stereo_ground_dem/DisparityPlaneFit.hpp"
#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/FarGroundSeeds.hpp"
#include "stereo_ground_dem/RisingGroundSeeds.hpp"
#include "stereo_ground_dem/EstimatorState.hpp"
#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/MapView.hpp"
#include "stereo_ground_dem/MotionPredictor.hpp"
#include "stereo_ground_dem/PoseSearch.hpp"
#include "stereo_ground_dem/SkylineMask.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/TemporalConsistency.hpp"
#include "stereo_ground_dem/TemporalVisibility.hpp"
#include "stereo_ground_dem/TrackingCheck.hpp"

namespace stereo_ground_dem {

struct IncrementalEstimatorOptions {
  StereoEstimatorOptions stereo;          ///< grid, ranges, hierarchy, aligner, start-up
  ElevationMapOptions map;                ///< its resolution is forced to stereo.grid_resolution_m
  bool use_map_prior = true;              ///< C_P: tie vertices to their fused map values
  double prior_weight = 1.0;              ///< scales the map information in C_P [-]
  int temporal_finest_level = 1;          ///< pyramid levels below this use the stereo pair only
  /// ... unless that level is narrower than this: then the temporal pairs go finer, down to the
  /// first level at least this wide (level 0 at most). Half-width KITTI images (613 px): level 0,
  /// 8x less drift over 200 m than level 1 (306 px) at no extra time (docs/results.md) [px].
  int min_temporal_width_px = 500;
  int tracking_levels = 2;                ///< mesh/pyramid levels used per tracked frame (<= mesh_levels)
  int iterations_per_level = 5;           ///< Gauss-Newton iterations per coarse level (>= 2)
  int fine_iterations = 3;                ///< ... at pyramid levels 0 and 1
  /// ... of the levels without the temporal pairs (level 0 at KITTI resolution), which start from
  /// the heights and motion of the level above (0: fine_iterations).
  int stereo_fine_iterations = 0;
  /// ... of the finest temporal level's second run, after the moving-texture test found texture
  /// to skip (0: fine_iterations).
  int repeat_iterations = 0;
  double nominal_frame_period_s = 0.1;    ///< used when stamps do not increase
  TrackingCheckOptions check;             ///< plausibility tests of a tracked frame
  DisparityPlaneFitOptions ground_plane;  ///< the pair's dominant plane (attitude hypotheses)
  TemporalConsistencyOptions temporal_consistency;  ///< moving texture skipped by the temporal pairs
  /// Texture that moved with the vehicle (flagged at the same image pixels in the last two frames:
  /// the shadow of a car driving ahead, the vehicle's own shadow) is skipped by this frame's
  /// temporal pairs from the pre-alignment on (the motion search after a failure does not skip
  /// it; nothing is carried while the test is off): left in until this frame's own test,
  /// it pulls the pre-alignment and the first joint pass toward standing still, and the test, run
  /// at the pulled pose, then misses it (docs/results.md, "Texture that moves with the vehicle").
  bool carry_moving_texture = true;
  /// When the moving-texture test sends the finest temporal level through a second pass, that pass
  /// starts from the prediction (the first of the pre-alignment's starts) instead of the first
  /// pass's pose if the prediction's cost per sample is clearly lower (below hypothesis_win_ratio
  /// times) with the flagged texture skipped: the first pass estimated the motion with that
  /// texture in (a car ahead and its shadow pull it toward standing still; docs/results.md, "The
  /// second pass from the prediction").
  bool repeat_from_prediction = true;
  SkylineMaskOptions skyline;             ///< the ground's outline against a blank background: skipped by them too
  /// Ground the previous camera did not see (hidden by the surface itself: behind a ridge, a
  /// crest, a ditch's rim) is skipped by the temporal pairs: tested after the first pass of the
  /// finest temporal level, at its pose and heights; when more than min_repeat_share of the
  /// level's samples are hidden, that level runs once more without them (docs/results.md, "Seeing
  /// past the crest").
  TemporalVisibilityOptions temporal_visibility;
  /// Where many pixels look past the surface (ObstacleDetector's far_depth_ratio: the far side of
  /// a crest), the unknown vertices under their rough points start at those points' heights and
  /// the obstacle test runs again on that surface (docs/results.md, "The far side of the crest").
  FarGroundSeedsOptions far_seeds;
  /// Ground rising out of the surface, which the obstacle test took for upright (an embankment)
  RisingGroundSeedsOptions rising_seeds;
  int reinit_after_failures = 3;          ///< consecutive failures before re-initialisation
  /// At re-initialisation, track the frame first from the stereo pair's pose (its height, pitch
  /// and roll from the ground in view, x, y and heading coasted) against the map and the last
  /// tracked frame's images, so that the map gives the heading and position; the stereo pair's
  /// surface is fused only when that fails the tracking check.
  bool relocalize_against_map = true;
  int prealign_level = 3;                 ///< pyramid level of the motion-only pre-alignment
  int prealign_iterations = 8;            ///< its Gauss-Newton iterations (0: none)
  int prealign_refine_iterations = 8;     ///< then at the next finer level when the motion surprised (0: never)
  /// A bound on the camera's acceleration [m/s^2] (0: none): when the pre-alignment of the
  /// predicted start moves the camera farther than max_acceleration_mps2 * gap^2 from the
  /// constant-velocity prediction (a 0.5 m change of a 1 m step in 0.1 s would take 50 m/s^2),
  /// something else pulled it (a car and its shadow, the far end of the view): the joint passes
  /// start from the prediction. 3 g: above the zoo's roughest drive (rolling, 21 m/s^2). The
  /// other starts' results must end within the same distance of the prediction, or they are no
  /// candidates (a start that walked the ground out of view: rolling seed 4, frame 18).
  double max_acceleration_mps2 = 30.0;
  /// The pre-alignment's largest trusted distance from the prediction after a stamp gap of gap_s:
  /// max_acceleration_mps2 x max(gap_s, nominal_frame_period_s)^2 [m]; infinite without a bound.
  double maxPrealignShiftM(double gap_s) const;
  /// With a velocity, the rotation and scale hypotheses (not the prediction, the straight step or
  /// the ground-anchored start) are pre-aligned with this many iterations, and the one that wins
  /// gets the rest of prealign_iterations (0 or >= prealign_iterations: all get all). On hard
  /// ground, where every start is tried each frame: pre-alignment time -37 % (rolling scene) and
  /// -42 % (moving shadows); frames where the first starts align are unchanged.
  int prealign_screen_iterations = 3;
  bool temporal_checkerboard = false;     ///< temporal pairs use every other pixel
  /// FrameResult::motion_information (the motion's information with the heights marginalized,
  /// for the ROS odometry covariance): one sparse Cholesky factorization per frame (~10 ms at
  /// full KITTI resolution). The offline runner does not use it and turns it off.
  bool motion_information = true;
  /// Also align the current left image with the previous RIGHT image (the paper's third pair).
  /// Off by default: that pair ties the motion to the stereo calibration, so a real rig's small
  /// rectification errors become a per-frame attitude bias (docs/method.md, section 6).
  bool use_cross_temporal_pair = false;
  /// Temporal pairs skip samples that land on the previous frame's obstacle pixels: ground
  /// uncovered by a moving car, or seen past a parked car's edge, is not compared with the car.
  bool exclude_previous_obstacles = false;
  /// The rectification's vertical misalignment (stereo.model_rectification) is measured on the
  /// first `rectification_startup_pairs` frames, then every `rectification_check_period_frames`
  /// frames (0: only on the first ones); about 5 ms each.
  int rectification_startup_pairs = 5;
  int rectification_check_period_frames = 10;
  double max_init_std_m = 0.15;           ///< map heights less certain are re-extended, not trusted [m]
  /// When the velocity is unknown (first tracked frame, after a failure), translations along the
  /// optical axis from motion_search_min_m to motion_search_max_m (per nominal frame period) are
  /// tried at the coarsest level and the cheapest starts the Gauss-Newton: far from the minimum
  /// the robust cost is too flat for Gauss-Newton to walk the whole way (measured on KITTI: it
  /// stalls at 0.3 m of a 1.2 m step).
  double motion_search_min_m = -1.0;
  double motion_search_max_m = 3.0;
  double motion_search_step_m = 0.2;
  double motion_search_max_reverse_m = 1.0;  ///< never more backwards, whatever the stamp gap [m]
  /// Attitude step of the rotation hypotheses tried when the constant-velocity start does not
  /// align as well as usual (MotionPredictor) [rad].
  double rotation_hypothesis_rad = 0.026;
  /// A pre-alignment start is good enough when its cost per sample is below this times the usual
  /// one (running over good frames); otherwise the next hypothesis is tried.
  double hypothesis_accept_ratio = 1.3;
  /// With a velocity, another start replaces the prediction only when its cost per sample after
  /// pre-alignment is below this times the prediction's (1: any cheaper start wins). The same
  /// margin lets the prediction replace the first pass's pose before repeat_from_prediction's
  /// second pass.
  double hypothesis_win_ratio = 0.9;
  /// Without a velocity, this many of the best-scoring search poses are aligned.
  int search_candidates = 3;
  /// 0: none; 1: the stereo-only finest level ends with an almost undamped step
  /// (SurfaceAlignerOptions::final_undamped_step); 2: every fine level.
  int final_undamped_step = 2;
  /// The levels that estimate the motion use vertices up to this camera depth only (0: all): far
  /// ground, seen by few pixels and held by the update constraint near its starting heights,
  /// would otherwise pull the pose toward a surface that is merely extrapolated [m].
  double motion_max_depth_m = 0.0;
  // input sanity (grey levels, 8-bit units)
  double min_mean_grey = 4.0;             ///< darker images are rejected
  double max_saturated_fraction = 0.5;    ///< more saturated pixels: rejected
  double min_std_grey = 2.0;              ///< flatter images are rejected (no texture)
  double frozen_mean_abs_diff_grey = 0.05;  ///< identical to the previous frame: rejected

  bool isValid(std::string* why) const;
};

enum class FrameStatus {
  kInitialized,      ///< stereo mode; defined the ground frame
  kTracked,          ///< estimated and fused
  kRecovered,        ///< after failures: re-localized against the map, or re-initialised from the stereo pair; fused
  kFailed,           ///< estimate implausible: pose predicted, map untouched
  kRejectedInput,    ///< bad images: nothing estimated, map untouched
};
const char* toString(FrameStatus s);

struct FrameResult {
  FrameStatus status = FrameStatus::kRejectedInput;
  std::string message;                 ///< reason for a failure or rejection
  int frame_index = -1;                ///< index of this call (counts every frame)
  double stamp_s = 0.0;
  Eigen::Isometry3d ground_T_camera = Eigen::Isometry3d::Identity();   ///< left camera in G
  Eigen::Isometry3d camera0_T_camera = Eigen::Isometry3d::Identity();  ///< KITTI convention
  std::array<PhotometricParams, 3> photometric;  ///< (L_k,R_k), (L_k,L_k-1), (L_k,R_k-1)
  GroundGrid window;                   ///< the local grid estimated this frame
  double time_ms = 0.0;
  double median_abs_residual_grey = 0.0;
  int valid_pixels = 0;
  int fused_vertices = 0;
  Matrix6d motion_information = Matrix6d::Zero();  ///< [1/m^2, 1/rad^2], twist (v, w) in camera
  std::vector<AlignmentReport> reports;  ///< per mesh level, coarse to fine
  // Where time_ms went (the rest: checks, fusion, the map's obstacle layer and bookkeeping):
  double pyramid_ms = 0.0;               ///< image pyramids and gradients of both images
  double prealign_ms = 0.0;              ///< motion-only pre-alignment over the starting poses
  double obstacle_ms = 0.0;              ///< occlusion reasoning
  double joint_ms = 0.0;                 ///< joint levels (heights, motion, photometry) and the consistency test
  double prealign_cost = 0.0;            ///< motion-only pre-alignment cost per sample (best start)
  /// camera position of the pre-alignment minus the prediction's [m] (NaN without a velocity or
  /// when no start aligned)
  double prealign_shift_m = std::numeric_limits<double>::quiet_NaN();
  bool prealign_rejected = false;        ///< ... beyond the acceleration bound: the prediction was kept
  int prealign_discarded = 0;            ///< other starts whose pre-alignment ended beyond that bound
  int temporal_finest_level = 0;  ///< finest pyramid level of the temporal pairs this frame (min_temporal_width_px)
  int moving_pixels = 0;  ///< ground pixels whose texture moved, skipped by the temporal pairs (test level)
  int hidden_pixels = 0;  ///< ground pixels the previous camera did not see (TemporalVisibility; its level)
  int carried_moving_pixels = 0;  ///< ... of the last two frames, skipped from the start (carry_moving_texture)
  bool repeat_from_prediction = false;  ///< the finest temporal level's second pass started from the prediction
  /// Median |residual| of the stereo pair and of the (current, previous left) pair at the finest
  /// level with motion [grey]: the stereo pair does not depend on the motion, so a temporal
  /// residual far above it means the motion is wrong (recorded in frames.csv; TrackingCheck fails a
  /// frame whose temporal residual is far above the usual level of good frames' temporal residuals).
  double stereo_residual_grey = 0.0;
  double temporal_residual_grey = 0.0;
  int obstacle_pixels = 0;               ///< at the obstacle test level
  int far_pixels = 0;                    ///< ... seeing past the surface (far_depth_ratio): excluded, no obstacle
  int far_seeded_vertices = 0;           ///< vertices started from those pixels' points or rays (FarGroundSeeds)
  int rising_seeded_vertices = 0;        ///< vertices started on ground rising out of the surface (RisingGroundSeeds)
  int far_carved_vertices = 0;           ///< ... of them: at the ray, which passed under their height
  /// Map heights a far ray passed under that this frame did not measure again: kept for the
  /// estimator, published as unknown until fused again (ElevationMap::markRefuted).
  int far_refuted_vertices = 0;
  int obstacle_vertices = 0;             ///< vertices hit by obstacle evidence this frame
  /// The rectification error modelled after this frame (zero when negligible or not modelled).
  VerticalMisalignment rectification;
};

class IncrementalEstimator {
 public:
  IncrementalEstimator(const StereoRig& rig, const IncrementalEstimatorOptions& options);

  /// Processes one stereo frame (any image type ImagePyramid accepts); stamps in seconds.
  FrameResult processFrame(const cv::Mat& left, const cv::Mat& right, double stamp_s,
                           ImagePyramid::ColorOrder order = ImagePyramid::ColorOrder::kBgr);

  bool initialized() const { return initialized_; }
  /// A velocity is known (false before the first tracked frame and after a failed one): the next
  /// frame's start then comes from a motion search, which finds steps of up to ~4 m.
  bool velocityKnown() const { return predictor_.velocityKnown(); }
  const ElevationMap& map() const { return map_; }
  /// The grey left image (CV_32F, 8-bit units, input resolution) of the last frame that moved the
  /// pose on (initialized, tracked or recovered); empty before the first. What OrthoTexture drapes.
  cv::Mat lastLeftImage() const { return prev_left_ ? prev_left_->level(0).image : cv::Mat(); }
  /// ... and its right image.
  cv::Mat lastRightImage() const { return prev_right_ ? prev_right_->level(0).image : cv::Mat(); }
  /// ... its obstacle pixels (CV_8U at the finest pyramid level the obstacle test gave; empty: none)
  /// and the texture its temporal pairs found moving (likewise; empty for a start-up or recovered
  /// frame): what PhotometricResidualMap::update should not hold against the surface.
  cv::Mat lastObstacleMask() const { return finestMask(prev_obstacles_); }
  cv::Mat lastMovingMask() const { return finestMask(prev_moving_); }
  ElevationMap& map() { return map_; }
  const Eigen::Isometry3d& groundTCamera0() const { return ground_T_camera0_; }
  const Eigen::Isometry3d& lastGroundTCamera() const { return ground_T_camera_; }
  int failures() const { return failures_total_; }
  int recoveries() const { return recoveries_; }
  int rejectedInputs() const { return rejected_total_; }
  const StereoRig& rig() const { return rig_; }
  const IncrementalEstimatorOptions& options() const { return options_; }
  /// Forgets everything (map, ground frame, trajectory).
  void reset();
  /// What the next frame depends on besides the map (EstimatorState.hpp). The images are shared,
  /// not copied (the estimator never writes into them).
  EstimatorState state() const;
  /// Continues from a saved state (with the map loaded separately into map()): the next frame is
  /// processed exactly as if it had followed the saved one in the same run. Throws
  /// std::invalid_argument, naming the problem, when the state does not fit this estimator (image
  /// size, pyramid levels, non-finite poses); the estimator is then unchanged.
  void restore(const EstimatorState& state);

  /// The disparity [px] the fused map implies at every pixel of a left camera at ground_T_camera
  /// (0 where there is no surface), at full resolution. Requires initialized().
  cv::Mat surfaceDisparity(const Eigen::Isometry3d& ground_T_camera) const;

  /// The window of the lattice covering the camera's working range from camera_T_ground.
  GroundGrid viewWindow(const Eigen::Isometry3d& camera_T_ground) const;

  /// The finest pyramid level of the temporal pairs for images image_width_px wide:
  /// temporal_finest_level, or finer where that level is narrower than min_temporal_width_px.
  int effectiveTemporalFinestLevel(int image_width_px) const;

 private:
  std::string checkImages(const ImagePyramid& left, const ImagePyramid& right) const;
  Eigen::Isometry3d predict(double stamp_s) const;
  /// A tracked frame; `relocalize_start` (camera_T_ground), when given, is its only starting pose
  /// (re-localization: the velocity is not known).
  FrameResult& trackFrame(double stamp_s, FrameResult* res, std::unique_ptr<ImagePyramid>& pl,
                          std::unique_ptr<ImagePyramid>& pr, const Eigen::Isometry3d* relocalize_start = nullptr);
  /// Step 3 of a tracked frame: the joint levels, coarse to fine, from the pre-aligned `state`,
  /// with the temporal-consistency test after the first level with motion (its moving texture
  /// joins `temporal_skipped`, returned in `moving`). Returns the finest level's report.
  AlignmentReport alignJointLevels(const ImagePyramid& pl, const ImagePyramid& pr, const GroundGrid& window,
                                   const ObstacleMask& obstacles, const HeightPrior& prior,
                                   std::array<AlignerTarget, 3> targets, std::vector<cv::Mat>* temporal_skipped,
                                   SurfaceAlignerOptions ao, SurfaceState* state, TemporalInconsistency* moving,
                                   FrameResult* res, const Eigen::Isometry3d& predicted);
  /// Step 4 of a tracked frame: which vertices of `window` the finest level's `report` measured
  /// (enough textured pixels, not seen mostly through obstacles, not at grazing incidence from
  /// camera_position); counts the well-known ones and those that jumped from `prior_mean`.
  std::vector<uint8_t> observedVertices(const GroundGrid& window, const Eigen::VectorXd& heights,
                                        const Eigen::Vector3d& camera_position, const AlignmentReport& report,
                                        const Eigen::VectorXd& prior_mean, const Eigen::VectorXd& info,
                                        int* well_known, int* jumps) const;
  FrameResult& recoverFrame(const ImagePyramid& left, const ImagePyramid& right, double stamp_s, FrameResult* res,
                            std::unique_ptr<ImagePyramid>& pl, std::unique_ptr<ImagePyramid>& pr);
  /// A failed frame: counted, never fused; its pose coasts at the last velocity, which the next
  /// frames no longer trust.
  FrameResult& failFrame(double stamp_s, const std::string& why, FrameResult* res);
  void advance(const Eigen::Isometry3d& ground_T_camera, double stamp_s, std::unique_ptr<ImagePyramid>& pl,
               std::unique_ptr<ImagePyramid>& pr, const std::vector<PhotometricParams>& photometric);
  bool rectificationDue(int frame_index) const;
  void addPairCheck(const StereoPairCheck& check);
  MotionPredictorOptions predictorOptions() const;
  PoseSearchOptions poseSearchOptions() const;
  /// The map as the camera sees it (windows, starting heights, the ground-anchored pose).
  MapView mapView() const;

  StereoRig rig_;
  IncrementalEstimatorOptions options_;
  StereoEstimator stereo_;
  RectificationMonitor rectification_;
  ElevationMap map_;
  bool initialized_ = false;
  Eigen::Isometry3d ground_T_camera0_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d ground_T_camera_ = Eigen::Isometry3d::Identity();  ///< last good frame
  MotionPredictor predictor_;    ///< last good pose and stamp, velocity
  TrackingCheck check_;
  SkylineMask skyline_;
  double residual_level_ = 0.0;  ///< running median |residual| of good frames [grey]
  double observed_level_ = 0.0;  ///< running number of ground vertices they observed
  double temporal_residual_level_ = 0.0;  ///< ... of their temporal pair (FrameResult::temporal_residual_grey)
  double prealign_level_ = 0.0;  ///< running pre-alignment cost per sample of good frames
  std::unique_ptr<ImagePyramid> prev_left_, prev_right_;
  static cv::Mat finestMask(const std::vector<cv::Mat>& levels) {
    for (const cv::Mat& m : levels)
      if (!m.empty()) return m;
    return cv::Mat();
  }
  std::vector<cv::Mat> prev_moving_;     ///< moving texture of the previous left image, per level (empty: none)
  std::vector<cv::Mat> carried_moving_;  ///< ... flagged in the frame before it too (empty: none)
  std::vector<cv::Mat> prev_obstacles_;  ///< obstacle pixels of the previous left image, per level
  cv::Mat last_left_level0_;   ///< for the frozen-frame test
  std::array<PhotometricParams, 3> last_photometric_;
  int frame_counter_ = 0;
  int consecutive_failures_ = 0;
  int failures_total_ = 0;
  int recoveries_ = 0;
  int rejected_total_ = 0;
};

}  // namespace stereo_ground_dem
