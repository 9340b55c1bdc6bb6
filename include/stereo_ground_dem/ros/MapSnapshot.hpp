#pragma once
/// \file MapSnapshot.hpp
/// The state the services read, published by the processing thread after every fused frame: a
/// copy of the map (services never touch the estimator's own map, so they answer while a frame is
/// processed and never see a half-fused one), the ground frame and the trajectory.

#include <ros/time.h>

#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/EstimatorState.hpp"
#include "stereo_ground_dem/OrthoTexture.hpp"
#include "stereo_ground_dem/PhotometricResidualMap.hpp"

namespace stereo_ground_dem {

struct MapSnapshot {
  std::shared_ptr<const ElevationMap> map;                ///< null: nothing mapped (yet, or since a reset)
  std::shared_ptr<const OrthoTexture> ortho;              ///< null when ortho_enabled is false (tiles shared: cheap)
  std::shared_ptr<const PhotometricResidualMap> residual; ///< null when residual_enabled is false (likewise)
  Eigen::Isometry3d ground_T_camera0 = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector2d> trajectory_xy;             ///< ground (x, y) of the left camera per frame
  ros::Time stamp;                                        ///< of the last fused frame
  long frame_count = 0;                                   ///< frames fused into this map
  /// The estimator's state after that frame (images shared), saved by ~save_map for ~load_map.
  std::shared_ptr<const EstimatorState> estimator;
  int image_width_px = 0, image_height_px = 0;
};

}  // namespace stereo_ground_dem
