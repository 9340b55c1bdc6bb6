#pragma once
/// \file DisparityPlaneFit.hpp
/// The dominant ground plane of a stereo pair from sparse matches: in a rectified pair a plane's
/// disparity is affine in the pixel, d = a u + b v + c, so a robust (RANSAC, then reweighted
/// least squares) fit of the matches below the horizon gives the plane in the camera frame,
/// whatever the camera's attitude: the start-up plane fit of the stereo mode needs a guess within
/// a few degrees, this does not. The incremental mode uses it for attitude hypotheses after
/// abrupt pitch or roll changes and for relocalization (IncrementalEstimator).

#include <Eigen/Core>
#include <string>
#include <vector>

#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

struct DisparityPlaneFitOptions {
  int ransac_iterations = 300;
  uint32_t seed = 1;                 ///< of the fixed sample sequence (repeatable results)
  double inlier_px = 0.6;            ///< inlier if |d - plane| <= inlier_px + inlier_share * d
  double inlier_share = 0.02;
  double min_disparity_px = 3.0;     ///< farther matches are ignored
  int min_inliers = 30;
  double min_height_m = 0.2;         ///< plausible camera heights above the plane [m]
  double max_height_m = 10.0;
  double max_tilt_rad = 0.7;         ///< the plane's normal within this of expected_down
  /// The ground's expected unit normal, toward the ground, in the camera frame (the camera's down
  /// axis for a level camera).
  Eigen::Vector3d expected_down = Eigen::Vector3d::UnitY();

  bool isValid(std::string* why) const;
  /// These options with the plane's normal within max_tilt_rad (if smaller than this->max_tilt_rad)
  /// of `down` (normalized): the ground a vehicle starts on is near the attitude its camera is
  /// mounted at, whereas the dominant plane of the matches may be a slope beside the track (an
  /// embankment tilted 32 deg beside a camera 0.8 m high, docs/results.md, "A low camera").
  DisparityPlaneFitOptions nearAttitude(const Eigen::Vector3d& down, double max_tilt_rad) const;
};

struct DisparityPlane {
  bool ok = false;
  std::string message;                              ///< why not ok
  Eigen::Vector3d down = Eigen::Vector3d::UnitY();  ///< unit normal toward the plane, camera frame
  double height_m = 0.0;                            ///< camera height above the plane [m]
  int inliers = 0;
  double rms_px = 0.0;                              ///< of the inliers about the plane [px]
};

class DisparityPlaneFit {
 public:
  explicit DisparityPlaneFit(const DisparityPlaneFitOptions& options = DisparityPlaneFitOptions());
  /// `points`: (u, v, disparity) at level 0 of `rig`.
  DisparityPlane fit(const std::vector<Eigen::Vector3f>& points, const StereoRig& rig) const;

 private:
  DisparityPlaneFitOptions options_;
};

}  // namespace stereo_ground_dem
