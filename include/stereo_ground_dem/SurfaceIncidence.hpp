#pragma once
/// \file SurfaceIncidence.hpp
/// How obliquely the camera sees the estimated surface at each vertex, relative to level ground
/// at the same place.
///
/// A patch of surface covers image area in proportion to the cosine between its normal and the
/// viewing ray. Level ground at a vertex is seen with cos_level = -d_z (d: the unit ray from the
/// camera centre to the vertex); the estimated surface with cos_est = -(n . d), n its unit normal
/// from the neighbouring heights. The ratio cos_est / cos_level is ~1 on gentle terrain, > 1 on a
/// face turned towards the camera (a curb, a rising slope), and near 0 or negative where the mesh
/// runs along the rays: the mesh draped from the top of a wall or rail down to the ground seen far
/// behind it (the ground in between is hidden), or the back of a crest. Such a vertex's height is
/// not measured by its pixels, whatever their number.

#include "stereo_ground_dem/GroundGrid.hpp"

#include <Eigen/Core>

namespace stereo_ground_dem {

class SurfaceIncidence {
 public:
  /// Per vertex of `grid` (heights `z` in the ground frame, NaN = no surface) the ratio
  /// cos_est / cos_level seen from `camera_centre_ground` (the camera centre in the ground frame
  /// [m]). The normal uses central differences where both neighbours are finite, one-sided ones
  /// at a border or a hole; NaN where a vertex has no finite neighbour along x or y, or the vertex
  /// is not below the camera's horizon (cos_level <= 0).
  static Eigen::VectorXd ratios(const GroundGrid& grid, const Eigen::VectorXd& z,
                                const Eigen::Vector3d& camera_centre_ground);
};

}  // namespace stereo_ground_dem
