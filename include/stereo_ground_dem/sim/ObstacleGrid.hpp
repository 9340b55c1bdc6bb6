#pragma once
/// \file ObstacleGrid.hpp
/// A uniform grid over the footprints of the static obstacles of a scene (boxes without velocity,
/// poles), so that a ray or a point is tested against the few obstacles near it instead of all of
/// them (guardrails are made of hundreds of boxes). Pure culling: the caller runs the exact tests
/// on the candidates, in index order, so the results do not depend on the grid.

#include <Eigen/Core>
#include <vector>

#include "stereo_ground_dem/sim/SceneOptions.hpp"

namespace stereo_ground_dem::sim {

class ObstacleGrid {
 public:
  ObstacleGrid() = default;
  /// Indexes the static obstacles of `options` in cells of `cell_m` [m].
  ObstacleGrid(const SceneOptions& options, double cell_m);

  bool empty() const { return cells_x_ == 0; }

  /// Appends the obstacle indices (0-based: boxes, then poles as boxes.size() + j) of the static
  /// obstacles whose footprint may meet the x-y trace of o + t d for t in [t0, t1], each once.
  void collectAlongRay(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, double t1,
                       std::vector<int>* ids) const;
  /// Appends the indices of the static obstacles whose footprint may contain (x, y).
  void collectAt(double x, double y, std::vector<int>* ids) const;

 private:
  double cell_m_ = 4.0;
  double x0_ = 0.0, y0_ = 0.0;  ///< corner of cell (0, 0)
  int cells_x_ = 0, cells_y_ = 0;
  std::vector<int> offsets_;  ///< cell c holds ids_[offsets_[c] .. offsets_[c + 1])
  std::vector<int> ids_;
};

}  // namespace stereo_ground_dem::sim
