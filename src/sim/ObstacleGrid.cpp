#include "stereo_ground_dem/sim/ObstacleGrid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace stereo_ground_dem::sim {

namespace {

// Footprints are enlarged by this much, so that rounding in the cell walk cannot miss one.
constexpr double kMarginM = 0.01;

struct Disc {
  Eigen::Vector2d c;
  double r;
  int id;
};

}  // namespace

ObstacleGrid::ObstacleGrid(const SceneOptions& options, const std::vector<double>& top_z,
                           double cell_m)
    : cell_m_(cell_m) {
  std::vector<Disc> discs;
  for (size_t i = 0; i < options.boxes.size(); ++i) {
    const BoxObstacle& b = options.boxes[i];
    if (b.velocity_xy.x() != 0.0 || b.velocity_xy.y() != 0.0) continue;
    discs.push_back({b.center_xy, 0.5 * std::hypot(b.length_m, b.width_m) + kMarginM,
                     static_cast<int>(i)});
  }
  for (size_t j = 0; j < options.poles.size(); ++j) {
    const PoleObstacle& p = options.poles[j];
    discs.push_back({p.xy, p.radius_m + kMarginM, static_cast<int>(options.boxes.size() + j)});
  }
  if (discs.empty()) return;
  double x_lo = std::numeric_limits<double>::infinity(), y_lo = x_lo;
  double x_hi = -x_lo, y_hi = -x_lo;
  for (const Disc& d : discs) {
    x_lo = std::min(x_lo, d.c.x() - d.r);
    y_lo = std::min(y_lo, d.c.y() - d.r);
    x_hi = std::max(x_hi, d.c.x() + d.r);
    y_hi = std::max(y_hi, d.c.y() + d.r);
  }
  x0_ = x_lo;
  y0_ = y_lo;
  cells_x_ = std::max(1, static_cast<int>(std::ceil((x_hi - x_lo) / cell_m_)));
  cells_y_ = std::max(1, static_cast<int>(std::ceil((y_hi - y_lo) / cell_m_)));
  std::vector<std::vector<int>> lists(static_cast<size_t>(cells_x_) * cells_y_);
  for (const Disc& d : discs) {
    const int ix0 = std::clamp(static_cast<int>(std::floor((d.c.x() - d.r - x0_) / cell_m_)), 0, cells_x_ - 1);
    const int ix1 = std::clamp(static_cast<int>(std::floor((d.c.x() + d.r - x0_) / cell_m_)), 0, cells_x_ - 1);
    const int iy0 = std::clamp(static_cast<int>(std::floor((d.c.y() - d.r - y0_) / cell_m_)), 0, cells_y_ - 1);
    const int iy1 = std::clamp(static_cast<int>(std::floor((d.c.y() + d.r - y0_) / cell_m_)), 0, cells_y_ - 1);
    for (int iy = iy0; iy <= iy1; ++iy) {
      for (int ix = ix0; ix <= ix1; ++ix) lists[static_cast<size_t>(iy) * cells_x_ + ix].push_back(d.id);
    }
  }
  offsets_.push_back(0);
  for (const auto& l : lists) {
    ids_.insert(ids_.end(), l.begin(), l.end());
    offsets_.push_back(static_cast<int>(ids_.size()));
    double top = -std::numeric_limits<double>::infinity();
    for (int id : l) top = std::max(top, top_z[static_cast<size_t>(id)] + kMarginM);
    cell_top_.push_back(top);
  }
}

void ObstacleGrid::collectAt(double x, double y, std::vector<int>* ids) const {
  if (empty()) return;
  const double fx = std::floor((x - x0_) / cell_m_), fy = std::floor((y - y0_) / cell_m_);
  if (!(fx >= 0.0 && fx < cells_x_ && fy >= 0.0 && fy < cells_y_)) return;
  const size_t c = static_cast<size_t>(fy) * cells_x_ + static_cast<size_t>(fx);
  ids->insert(ids->end(), ids_.begin() + offsets_[c], ids_.begin() + offsets_[c + 1]);
}

}  // namespace stereo_ground_dem::sim
