#pragma once
/// \file TrackingCheck.hpp
/// The plausibility tests of a tracked frame (METHOD.md section 6, step 7): a frame that fails
/// one is not fused, its pose follows the prediction, and the map stays untouched.

#include <limits>
#include <string>

#include "stereo_ground_dem/Se3.hpp"

namespace stereo_ground_dem {

struct TrackingCheckOptions {
  double max_speed_m_per_s = 50.0;        ///< faster estimated motion is implausible
  /// Faster rotation is implausible: an off-road vehicle crossing a ditch at 10 m/s pitches by
  /// 9 degrees in 0.1 s (1.6 rad/s, the rendered `rolling` scene).
  double max_turn_rate_rad_per_s = 3.0;
  double max_height_jump_m = 0.4;         ///< a well-known vertex moving this far is implausible ...
  double max_jump_fraction = 0.15;        ///< ... for more than this fraction of them
  double max_outside_fraction = 0.6;      ///< more samples warped outside the images: failure
  /// Median residual above ratio * the usual level and above usual + max_residual_increase_grey
  /// is a failure; the same for the temporal pair's residual against its own usual level.
  double max_residual_ratio = 3.0;
  double max_residual_increase_grey = 3.0;  ///< [grey]
  int min_samples = 500;                  ///< fewer pixel samples in the final level: failure
  /// Fewer ground vertices observed than this fraction of the usual number: the ground support
  /// collapsed (an image without the ground, an upside-down or foreign pair), failure. On the
  /// zoo and both KITTI clips the fewest is 0.56 of the running level; 0.32 from a 0.8 m mount at
  /// a crest's top.
  double min_observed_fraction = 0.2;

  bool isValid(std::string* why) const;
};

/// What a tracked frame's estimate says about itself.
struct TrackingEvidence {
  bool degenerate = false;        ///< the normal equations could not be solved
  bool finite = true;             ///< pose and heights finite
  Vector6d step = Vector6d::Zero();  ///< previous camera -> current camera (twist)
  double dt_s = 0.1;              ///< stamp gap [s]
  int samples = 0;                ///< pixel samples of the final level (valid + outside)
  int outside = 0;                ///< ... warped outside their target
  int well_known = 0;             ///< vertices whose map height was well known (std < ~3 cm)
  int jumps = 0;                  ///< ... that moved more than max_height_jump_m
  double median_residual_grey = 0.0;
  double usual_residual_grey = 0.0;  ///< running level of good frames (0: unknown yet)
  /// The previous left image against this one at the finest temporal level [grey]:
  /// the motion's own test. The final level may align the stereo pair alone (temporal_finest_level
  /// > 0), whose residual does not see a wrong motion. 0 or NaN: not measured.
  double temporal_residual_grey = std::numeric_limits<double>::quiet_NaN();
  double usual_temporal_residual_grey = 0.0;  ///< running level of good frames (0: unknown yet)
  /// This frame's stamp gap over the gap the usual temporal level was learnt at (>= 1): the two
  /// images differ more the farther the camera moved between them (occlusions, viewpoint, light),
  /// and the temporal limit grows with it. A node that dropped 10 frames (KITTI raw 0013, a 1.1 s
  /// step after 0.1-0.2 s ones) still aligned the step, 4.7 grey against a usual 1.0.
  double temporal_gap_ratio = 1.0;
  int observed_vertices = 0;               ///< ground vertices this frame observed (would fuse)
  double usual_observed_vertices = 0.0;    ///< running level of good frames (0: unknown yet)
};

class TrackingCheck {
 public:
  explicit TrackingCheck(const TrackingCheckOptions& options);
  /// Empty when the frame is plausible, else a one-line reason naming the numbers.
  std::string failure(const TrackingEvidence& e) const;
  const TrackingCheckOptions& options() const { return options_; }

 private:
  TrackingCheckOptions options_;
};

}  // namespace stereo_ground_dem
