#pragma once
/// \file RayCaster.hpp
/// Exact ray casting into a SyntheticScene: the terrain (TerrainModel, marched with the safe steps
/// its slope and curvature bounds allow, vertical faces on feature lines hit exactly) and the
/// obstacles (boxes and poles, placed at the time of the ray), plus the obstacle footprints.

#include <Eigen/Core>
#include <limits>
#include <memory>
#include <vector>

#include "stereo_ground_dem/sim/ObstacleGrid.hpp"
#include "stereo_ground_dem/sim/SceneOptions.hpp"
#include "stereo_ground_dem/sim/SurfaceHit.hpp"
#include "stereo_ground_dem/sim/TerrainModel.hpp"

namespace stereo_ground_dem::sim {

class RayCaster {
 public:
  /// `options` must be valid; `terrain` is the options' terrain.
  RayCaster(std::shared_ptr<const TerrainModel> terrain, const SceneOptions& options);

  const TerrainModel& terrain() const { return *terrain_; }
  int obstacleCount() const { return static_cast<int>(options_.boxes.size() + options_.poles.size()); }

  /// The nearest surface (terrain or obstacle) hit by the ray o + t d, 0 < t <= t_max (d need
  /// not be unit). Exact up to ~1e-6 m along z for the terrain, to rounding for obstacles.
  SurfaceHit intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max,
                       double time_s = 0.0) const;
  /// The nearest terrain hit only.
  SurfaceHit intersectTerrain(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                              double t_max) const;
  /// The nearest obstacle hit only (obstacles at time_s).
  SurfaceHit intersectObstacles(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max,
                                double time_s) const;

  /// Whether the ray o + t d, t > 0, meets an obstacle at time_s (d pointing up: a shadow ray).
  bool blockedUpwards(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double time_s) const {
    if (!(d.z() > 0.0)) return intersectObstacles(o, d, std::numeric_limits<double>::infinity(), time_s).hit();
    // Above the highest obstacle the ray meets none.
    const double t_top = (obstacle_z_hi_ - o.z()) / d.z();
    return t_top > 0.0 && intersectObstacles(o, d, t_top, time_s).hit();
  }

  /// Object id of an obstacle whose footprint contains (x, y) at time_s, 0 if none.
  int obstacleIdAt(double x, double y, double time_s = 0.0) const;
  /// Terrain height, or the top of an obstacle whose footprint contains (x, y) at time_s.
  double surfaceHeight(double x, double y, double time_s = 0.0) const;

 private:
  /// Whether (x, y) lies in the footprint of obstacle `index` (0-based: boxes, then poles).
  bool insideFootprint(int index, double x, double y, double time_s) const;

  std::shared_ptr<const TerrainModel> terrain_;
  SceneOptions options_;
  /// Per box, what every ray test needs.
  struct BoxCache {
    bool moving = false;
    double cos_yaw = 1.0, sin_yaw = 0.0;
    double radius = 0.0;     ///< of the footprint's circumscribed circle (+ 1e-9) [m]
    double terrain_z = 0.0;  ///< terrain height at the centre (static boxes) [m]
  };
  std::vector<BoxCache> box_cache_;
  std::vector<double> pole_terrain_z_;  ///< terrain height at each pole's axis [m]
  ObstacleGrid grid_;               ///< static obstacles, when there are many
  std::vector<int> moving_boxes_;   ///< indices of the boxes with a velocity
  double obstacle_z_lo_ = 0.0;      ///< every obstacle lies in this slab [m]
  double obstacle_z_hi_ = 0.0;
};

}  // namespace stereo_ground_dem::sim
