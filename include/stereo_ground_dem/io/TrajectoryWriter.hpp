#pragma once
/// \file TrajectoryWriter.hpp
/// Camera trajectories in the two formats evaluation tools read:
///  - KITTI odometry: one line per frame, the 12 numbers of the 3x4 row-major [R | t] of
///    camera0_T_cameraK (pose of frame k's left camera in frame 0's left camera frame);
///  - TUM RGB-D: "t tx ty tz qx qy qz qw" per line (stamp [s], translation [m], unit quaternion),
///    lines starting with '#' are comments.
/// Numbers are written in their shortest round-trip form, so write-then-read is exact.
/// Readers and writers throw std::runtime_error with the path (and line number) on failure.

#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace stereo_ground_dem {

struct StampedTrajectory {
  std::vector<double> stamps_s;          ///< [s]
  std::vector<Eigen::Isometry3d> poses;  ///< same length as stamps_s
};

class TrajectoryWriter {
 public:
  static void writeKitti(const std::string& path, const std::vector<Eigen::Isometry3d>& poses);
  /// stamps_s and poses must have the same length.
  static void writeTum(const std::string& path, const std::vector<double>& stamps_s,
                       const std::vector<Eigen::Isometry3d>& poses);

  /// Blank lines are skipped; a line without exactly 12 numbers, or whose 3x3 block is not a
  /// rotation (|R^T R - I| > 1e-3), throws "path:line: reason". The numbers are kept as read.
  static std::vector<Eigen::Isometry3d> readKitti(const std::string& path);
  /// Blank and '#' lines are skipped; quaternions are normalised (a zero one throws).
  static StampedTrajectory readTum(const std::string& path);
};

}  // namespace stereo_ground_dem
