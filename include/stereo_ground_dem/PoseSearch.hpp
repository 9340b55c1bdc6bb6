#pragma once
/// \file PoseSearch.hpp
/// Where the camera of a new frame is before the joint levels run (IncrementalEstimator, steps 0
/// and 1 of a tracked frame): the relocalization of a frame without a known velocity (the first
/// tracked frame, after a failure, after a restore) and the motion-only pre-alignment of the
/// starting poses against the map's surface.
///
/// - rankedStarts(): every pose of the predictor's search grid (steps along the optical axis,
///   headings, then pitches) scored by its photometric cost against the previous left image at
///   the coarsest level, without iterating; the local minima along the step, best first.
/// - prealign(): motion only, at a coarse level, from the starts in order until one aligns about
///   as well as the usual frame; refined one level finer when the motion surprised; rejected
///   when it moved the camera farther from the prediction than an acceleration bound allows
///   (with a velocity, the other starts' results must end within that bound as well).
///
/// A search is made per frame: it holds pointers to the estimator's rig, stereo estimator, map
/// view, predictor and previous images (PoseSearchContext), which must outlive it.

#include <Eigen/Geometry>
#include <array>
#include <limits>
#include <opencv2/core.hpp>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/MapView.hpp"
#include "stereo_ground_dem/MotionPredictor.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/SurfaceAligner.hpp"

namespace stereo_ground_dem {

/// The photometric slots (0 stereo, 1 previous left, 2 previous right) of the pairs in use: the
/// stereo pair alone, with the previous left image (temporal), and the previous right (cross).
std::vector<int> pairSlots(bool temporal, bool cross);

/// The IncrementalEstimatorOptions a search uses (documented there under the same names).
struct PoseSearchOptions {
  SurfaceAlignerOptions aligner;   ///< the stereo options' aligner (motion is switched on or off per step)
  int search_level = 3;           ///< pyramid level of the relocalization's scores (the coarsest mesh level)
  int search_candidates = 3;       ///< local minima of the scores aligned without a velocity
  int prealign_level = 3;
  int prealign_iterations = 8;
  int prealign_screen_iterations = 3;
  int prealign_refine_iterations = 8;
  double hypothesis_accept_ratio = 1.3;
  double hypothesis_win_ratio = 0.9;
  double nominal_frame_period_s = 0.1;  ///< a gap longer than 1.5 of these surprises (refinement) [s]
  bool use_cross_temporal_pair = false;
};

/// What a search reads from its estimator (pointers: none is owned; all required).
struct PoseSearchContext {
  const StereoRig* rig = nullptr;
  const StereoEstimator* stereo = nullptr;   ///< photometric statistics, the pair's sparse matches
  const MapView* map = nullptr;              ///< windows, starting heights, the ground-anchored pose
  const MotionPredictor* predictor = nullptr;  ///< velocity, search grid, the last pose
  const ImagePyramid* prev_left = nullptr;   ///< the last good frame's images
  const ImagePyramid* prev_right = nullptr;
  Eigen::Isometry3d prev_camera_T_ground = Eigen::Isometry3d::Identity();  ///< ... and its pose
};

/// One frame's pre-alignment problem.
struct PrealignRequest {
  const ImagePyramid* left = nullptr;
  const ImagePyramid* right = nullptr;
  /// camera_T_ground starts, the prediction first (with a velocity: MotionPredictor::hypotheses;
  /// without: rankedStarts and their attitude steps)
  std::vector<Eigen::Isometry3d> starts;
  /// the ground-anchored start among them (none: max); without one, it is inserted after the
  /// first two starts when those do not align
  size_t anchored_index = std::numeric_limits<size_t>::max();
  std::array<AlignerTarget, 3> targets;  ///< stereo, previous left, previous right (pyramids, poses, masks)
  double gap_s = 0.1;                    ///< since the last good frame [s]
  /// the prediction's alignment may move the camera this far from it (infinite: no bound) [m]
  double max_shift_m = std::numeric_limits<double>::infinity();
  /// running cost per sample of good frames' pre-alignments (0: not known yet)
  double usual_cost = 0.0;
};

/// Its result: the pose and the three pairs' photometric parameters to start the joint levels
/// from (the prediction's, with statistics, when nothing aligned or the result was rejected),
/// the window at the last start tried with its starting heights, and the figures.
struct Prealignment {
  Eigen::Isometry3d camera_T_ground = Eigen::Isometry3d::Identity();
  std::vector<PhotometricParams> photometric;  ///< stereo, previous left, previous right
  GroundGrid window;
  Eigen::VectorXd heights, information;
  std::vector<AlignmentReport> reports;        ///< every alignment run, in order
  double cost = std::numeric_limits<double>::infinity();  ///< per sample, the chosen start (infinite: none)
  /// distance of the result from the prediction (NaN without a velocity or an aligned start) [m]
  double shift_m = std::numeric_limits<double>::quiet_NaN();
  bool rejected = false;                       ///< beyond max_shift_m: the prediction is used
  /// other starts whose alignment ended beyond max_shift_m from the prediction (no candidates)
  int discarded = 0;
};

class PoseSearch {
 public:
  PoseSearch(const PoseSearchOptions& options, const PoseSearchContext& context);

  /// Relocalization without a velocity: the best `search_candidates` poses of the predictor's
  /// search grid for an image stamped stamp_s (the temporal pair skips `skipped`, per level).
  std::vector<Eigen::Isometry3d> rankedStarts(const ImagePyramid& left, double stamp_s,
                                              const std::vector<cv::Mat>& skipped) const;

  /// Motion only, at prealign_level, from the request's starts in order (all of them without a
  /// velocity) until one aligns about as well as the usual frame; see the file comment.
  Prealignment prealign(PrealignRequest request) const;

 private:
  PhotometricParams statsPhotometric(const ImagePyramid& ref, const ImagePyramid& other,
                                     const Eigen::Isometry3d& camera_T_ground) const;
  PoseSearchOptions options_;
  PoseSearchContext c_;
};

}  // namespace stereo_ground_dem
