#pragma once
/// \file SurfaceHit.hpp
/// The result of casting a ray into a SyntheticScene (RayCaster).

#include <Eigen/Core>
#include <limits>

namespace stereo_ground_dem::sim {

/// The nearest surface along a ray.
struct SurfaceHit {
  // Values of `surface`.
  static constexpr int kTerrainTop = 0;
  static constexpr int kTerrainFaceX = 1;  ///< vertical terrain face on a line x = const
  static constexpr int kTerrainFaceY = 2;  ///< vertical terrain face on a line y = const
  /// Box faces: kBoxFaceBase + 2 * axis + (positive side ? 1 : 0); axis 0 length, 1 width, 2 up.
  static constexpr int kBoxFaceBase = 10;
  static constexpr int kPoleSide = 20;
  static constexpr int kPoleTop = 21;

  double t = std::numeric_limits<double>::infinity();  ///< ray parameter (point = o + t d)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    ///< [m], ground frame
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit, facing the ray origin
  int object_id = -1;  ///< 0 terrain, > 0 obstacle, -1 nothing hit
  int surface = kTerrainTop;  ///< which part of the object (see the constants above)
  bool hit() const { return object_id >= 0; }
};

}  // namespace stereo_ground_dem::sim
