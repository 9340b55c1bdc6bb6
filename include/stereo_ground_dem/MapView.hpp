#pragma once
/// \file MapView.hpp
/// What the elevation map offers a camera pose (IncrementalEstimator, PoseSearch): the window of
/// the lattice that the camera's working range covers, the starting heights on it (the map's
/// well-known heights, the rest extended from them) and the pose that a stereo pair's dominant
/// plane gives against the map's local plane ahead.
///
/// A view holds references to the rig, the options and the map: it is made where it is used and
/// must not outlive them.

#include <Eigen/Geometry>

#include "stereo_ground_dem/DisparityPlaneFit.hpp"
#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

class MapView {
 public:
  /// stereo: the grid resolution, the ranges, the nominal height and the mesh levels;
  /// max_init_std_m: map heights less certain than this are re-extended, not trusted [m];
  /// ground_plane: the pair's dominant plane (groundAnchoredPose).
  MapView(const StereoRig& rig, const StereoEstimatorOptions& stereo, double max_init_std_m,
          const DisparityPlaneFitOptions& ground_plane, const ElevationMap& map)
      : rig_(rig), stereo_(stereo), max_init_std_m_(max_init_std_m), ground_plane_(ground_plane), map_(map) {}

  /// The window of the lattice covering the camera's working range from camera_T_ground (plus a
  /// 2 m margin, aligned to the coarsest mesh level's spacing).
  GroundGrid window(const Eigen::Isometry3d& camera_T_ground) const;

  /// The starting heights on `window` and their information: the map's, where known to better
  /// than max_init_std_m; elsewhere a plane fitted to the known ones (the level plane under the
  /// camera without 20 of them) relaxed towards the harmonic extension of the known heights (60
  /// Gauss-Seidel sweeps), with information 0. Finite `seeds` (FarGroundSeeds) replace the map's
  /// heights, known or not: they are kept with information 0, and the unknown
  /// heights are then the converged harmonic extension (sparse Cholesky), so that the band between
  /// the known ground and the seeds does not stand above both (`converged_with_seeds`; false: the
  /// 60 sweeps as without seeds).
  void initialHeights(const GroundGrid& window, const Eigen::Isometry3d& camera_T_ground, Eigen::VectorXd* heights,
                      Eigen::VectorXd* information, const Eigen::VectorXd* seeds = nullptr,
                      bool converged_with_seeds = true) const;

  /// The pose whose height and attitude above the ground come from the pair's dominant plane
  /// (DisparityPlaneFit on the sparse matches of `check`) and the map's local plane 4-15 m ahead,
  /// with position and heading from `guess` (camera_T_ground). False when the pair has no plane.
  bool groundAnchoredPose(const StereoPairCheck& check, const Eigen::Isometry3d& guess, Eigen::Isometry3d* out) const;

 private:
  const StereoRig& rig_;
  const StereoEstimatorOptions& stereo_;
  double max_init_std_m_;
  const DisparityPlaneFitOptions& ground_plane_;
  const ElevationMap& map_;
};

}  // namespace stereo_ground_dem
