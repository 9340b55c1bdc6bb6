#pragma once
/// \file TrackingCheck.hpp
/// The plausibility tests of a tracked frame (METHOD.md section 6, step 7): a frame that fails
/// one is not fused, its pose follows the prediction, and the map stays untouched.

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
  double max_residual_ratio = 3.0;        ///< median residual above ratio * the usual level ...
  double max_residual_increase_grey = 3.0;  ///< ... and above usual + this is a failure [grey]
  int min_samples = 500;                  ///< fewer pixel samples in the final level: failure

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
