#pragma once
/// \file ObstacleGrid.hpp
/// A uniform grid over the footprints of the static obstacles of a scene (boxes without velocity,
/// poles), so that a ray or a point is tested against the few obstacles near it instead of all of
/// them (guardrails are made of hundreds of boxes). Pure culling: the caller runs the exact tests
/// on the candidates; only which of two obstacles hit at exactly the same distance wins can
/// depend on the grid.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "stereo_ground_dem/sim/SceneOptions.hpp"

namespace stereo_ground_dem::sim {

class ObstacleGrid {
 public:
  ObstacleGrid() = default;
  /// Indexes the static obstacles of `options` in cells of `cell_m` [m]; `top_z[i]` is the
  /// highest point of obstacle i (0-based: boxes, then poles as boxes.size() + j) [m].
  ObstacleGrid(const SceneOptions& options, const std::vector<double>& top_z, double cell_m);

  bool empty() const { return cells_x_ == 0; }

  /// Walks the cells that the x-y trace of o + t d crosses for t in [t0, t1], nearest first,
  /// skipping cells whose obstacles all lie below the ray there. For each other cell calls
  /// visit(ids, count, t_exit) with the cell's obstacle indices and the ray parameter where it
  /// leaves the cell; stops when visit returns false.
  template <typename Visit>
  void walk(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, double t1,
            Visit visit) const;

  /// Appends the indices of the static obstacles whose footprint may contain (x, y).
  void collectAt(double x, double y, std::vector<int>* ids) const;

 private:
  double cell_m_ = 4.0;
  double x0_ = 0.0, y0_ = 0.0;  ///< corner of cell (0, 0)
  int cells_x_ = 0, cells_y_ = 0;
  std::vector<int> offsets_;     ///< cell c holds ids_[offsets_[c] .. offsets_[c + 1])
  std::vector<int> ids_;
  std::vector<double> cell_top_; ///< highest obstacle point in each cell [m]
};

template <typename Visit>
void ObstacleGrid::walk(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, double t1,
                        Visit visit) const {
  if (empty() || !(t1 >= t0)) return;
  // Clip [t0, t1] to the grid's rectangle.
  const double lo[2] = {x0_, y0_};
  const double hi[2] = {x0_ + cells_x_ * cell_m_, y0_ + cells_y_ * cell_m_};
  double ta = t0, tb = t1;
  for (int a = 0; a < 2; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return;
      continue;
    }
    double u0 = (lo[a] - o[a]) / d[a], u1 = (hi[a] - o[a]) / d[a];
    if (u0 > u1) std::swap(u0, u1);
    ta = std::max(ta, u0);
    tb = std::min(tb, u1);
  }
  if (!(ta <= tb)) return;
  // Walk the cells the trace crosses (Amanatides and Woo).
  const double px = o.x() + ta * d.x(), py = o.y() + ta * d.y();
  int ix = std::clamp(static_cast<int>(std::floor((px - x0_) / cell_m_)), 0, cells_x_ - 1);
  int iy = std::clamp(static_cast<int>(std::floor((py - y0_) / cell_m_)), 0, cells_y_ - 1);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int step_x = d.x() > 0.0 ? 1 : -1, step_y = d.y() > 0.0 ? 1 : -1;
  double next_x = kInf, next_y = kInf, delta_x = kInf, delta_y = kInf;
  if (d.x() != 0.0) {
    next_x = (x0_ + (ix + (step_x > 0 ? 1 : 0)) * cell_m_ - o.x()) / d.x();
    delta_x = cell_m_ / std::abs(d.x());
  }
  if (d.y() != 0.0) {
    next_y = (y0_ + (iy + (step_y > 0 ? 1 : 0)) * cell_m_ - o.y()) / d.y();
    delta_y = cell_m_ / std::abs(d.y());
  }
  double t_in = ta;
  for (;;) {
    const double t_out = std::min(std::min(next_x, next_y), tb);
    const size_t c = static_cast<size_t>(iy) * cells_x_ + static_cast<size_t>(ix);
    const int n = offsets_[c + 1] - offsets_[c];
    // The lowest point of the ray in the cell is at one of its ends.
    const double z_low = o.z() + (d.z() < 0.0 ? t_out : t_in) * d.z();
    if (n > 0 && z_low <= cell_top_[c] && !visit(ids_.data() + offsets_[c], n, t_out)) return;
    if (t_out >= tb) return;
    t_in = t_out;
    if (next_x < next_y) {
      ix += step_x;
      next_x += delta_x;
      if (ix < 0 || ix >= cells_x_) return;
    } else {
      iy += step_y;
      next_y += delta_y;
      if (iy < 0 || iy >= cells_y_) return;
    }
  }
}

}  // namespace stereo_ground_dem::sim
