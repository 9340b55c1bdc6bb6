#pragma once
/// \file GroundAttitudeEstimator.hpp
/// The camera's height, pitch and roll above the LOCAL ground: a plane fitted to the fused map
/// around the camera's nadir (the ground under and behind the vehicle, seen in earlier frames,
/// and the near ground ahead). Unlike the pose in the ground frame G (level at the first frame),
/// these say how the camera sits on the terrain it drives on: a slowly changing height or pitch on
/// level road is a camera mount that moved, or an estimate that drifts.
///
/// Angles follow REP 103 for a body frame x forward, y left, z up (the camera's z, -x, -y):
/// pitch is the rotation about the left axis, positive with the optical axis below the local
/// ground plane (nose down); roll is the rotation about the forward axis, positive with the
/// left side up.

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "stereo_ground_dem/ElevationMap.hpp"

namespace stereo_ground_dem {

struct GroundAttitudeOptions {
  double radius_m = 8.0;      ///< map vertices within this horizontal distance of the nadir [m] (<= 100)
  /// Fewer of the disc's vertices known: no estimate. The ground ahead alone (the first frames)
  /// says little about the ground under the vehicle (on a crest, 1 deg off).
  double min_coverage = 0.6;
  double outlier_m = 0.15;    ///< vertices farther from the first plane are left out of the second fit [m]
  /// mountWarning(): the typical attitude of the last mount_window_frames mapped frames may differ
  /// this much from the one at the start of the map.
  double mount_height_tolerance_m = 0.2;
  double mount_angle_tolerance_rad = 0.05;  ///< (2.9 deg) pitch and roll
  int mount_window_frames = 30;             ///< frames whose medians are compared
  int mount_min_estimates = 20;             ///< fewer valid estimates in a window: no judgement

  bool isValid(std::string* why) const;
};

/// One estimate; valid == false (and NaN values) when the map knows too little there.
struct GroundAttitudeEstimate {
  bool valid = false;
  double height_m;            ///< camera centre above the plane, along its normal [m]
  double pitch_rad;           ///< REP 103 pitch relative to the plane (positive: looking down)
  double roll_rad;            ///< REP 103 roll relative to the plane (positive: left side up)
  double slope_rad;           ///< the plane's inclination from level (G's x-y plane)
  double rms_m;               ///< RMS height residual of the vertices used [m]
  int vertices = 0;           ///< known vertices used in the final fit
  GroundAttitudeEstimate();
};

class GroundAttitudeEstimator {
 public:
  explicit GroundAttitudeEstimator(const GroundAttitudeOptions& options = GroundAttitudeOptions());

  /// From the fused map around the camera at `ground_T_camera` (camera x right, y down, z forward).
  GroundAttitudeEstimate estimate(const ElevationMap& map, const Eigen::Isometry3d& ground_T_camera) const;

  /// The attitude of a camera above the plane z = a x + b y + c of G (the geometry alone).
  static GroundAttitudeEstimate relativeToPlane(const Eigen::Vector3d& abc, const Eigen::Isometry3d& ground_T_camera);

  /// The medians (height, pitch, roll) of the valid estimates; valid when there are at least
  /// mount_min_estimates of them. One frame over a bump does not move it.
  GroundAttitudeEstimate typical(const std::vector<GroundAttitudeEstimate>& estimates) const;

  /// "" when the camera sits on the ground as it did at `reference` (typical() of the first
  /// frames of the map), else one line saying what moved: a mount that slipped, or an estimate
  /// that drifts. Also "" while either is not known.
  std::string mountWarning(const std::vector<GroundAttitudeEstimate>& recent, const GroundAttitudeEstimate& reference) const;

  const GroundAttitudeOptions& options() const { return options_; }

 private:
  GroundAttitudeOptions options_;
};

}  // namespace stereo_ground_dem
