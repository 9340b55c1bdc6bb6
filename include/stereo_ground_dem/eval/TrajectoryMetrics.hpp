#pragma once
/// \file TrajectoryMetrics.hpp
/// Trajectory accuracy against ground truth, both given as camera0_T_cameraK (KITTI convention).

#include <Eigen/Geometry>
#include <vector>

namespace stereo_ground_dem {

struct SegmentError {
  double length_m = 0.0;
  int count = 0;                  ///< segments of this length evaluated
  double translation_pct = 0.0;   ///< mean translation error / length [%]
  double rotation_deg_per_m = 0.0;  ///< mean rotation error / length [deg/m]
};

struct TrajectoryMetrics {
  int frames = 0;
  double path_length_m = 0.0;            ///< of the ground truth
  double end_translation_error_m = 0.0;  ///< |t_est - t_gt| at the last frame
  double end_drift_pct = 0.0;            ///< end error / path length [%]
  double end_rotation_error_deg = 0.0;
  double max_rotation_error_deg = 0.0;   ///< of any frame, absolute
  // per-frame relative motion errors (frame k-1 -> k)
  double rel_translation_mean_m = 0.0, rel_translation_median_m = 0.0, rel_translation_max_m = 0.0;
  double rel_rotation_mean_deg = 0.0, rel_rotation_median_deg = 0.0, rel_rotation_max_deg = 0.0;
  std::vector<double> rel_translation_m, rel_rotation_deg, abs_rotation_deg;  ///< per frame
  std::vector<SegmentError> segments;   ///< KITTI-style, for segment lengths within the path

  /// Compares the first min(est, gt) frames. `segment_lengths_m` as KITTI (100..800 m) by default
  /// scaled to short sequences: 10, 20, 30, 40, 50 m.
  static TrajectoryMetrics compute(const std::vector<Eigen::Isometry3d>& estimate,
                                   const std::vector<Eigen::Isometry3d>& truth,
                                   const std::vector<double>& segment_lengths_m = {10, 20, 30, 40, 50});
};

}  // namespace stereo_ground_dem
