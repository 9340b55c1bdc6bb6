#include "stereo_ground_dem/FarGroundSeeds.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace stereo_ground_dem {

bool FarGroundSeedsOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (min_far_pixels < 0) return bad("min_far_pixels must be >= 0");
  if (min_points < 1) return bad("min_points must be >= 1");
  if (!(min_drop_m >= 0.0)) return bad("min_drop_m must be >= 0");
  if (!(ray_share > 0.0 && ray_share <= 1.0)) return bad("ray_share must be in (0, 1]");
  if (!(ceiling_margin_m >= 0.0)) return bad("ceiling_margin_m must be >= 0");
  return true;
}

FarGroundSeeds::FarGroundSeeds(const FarGroundSeedsOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("FarGroundSeedsOptions: " + why);
}

Eigen::VectorXd FarGroundSeeds::seeds(const GroundGrid& grid, const Eigen::VectorXd& heights,
                                      const Eigen::VectorXd& information,
                                      const std::vector<Eigen::Vector3d>& points) const {
  const int n = grid.vertexCount();
  Eigen::VectorXd out = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  if (n == 0 || points.empty()) return out;
  // Each point counts for the (up to four) vertices of its grid cell: within one spacing of each.
  std::vector<std::vector<double>> z(static_cast<size_t>(n));
  for (const Eigen::Vector3d& p : points) {
    if (p.allFinite()) grid.forCellVertices(p.x(), p.y(), [&](int v) { z[static_cast<size_t>(v)].push_back(p.z()); });
  }
  for (int v = 0; v < n; ++v) {
    std::vector<double>& zv = z[static_cast<size_t>(v)];
    if (information[v] > 0.0 || static_cast<int>(zv.size()) < options_.min_points) continue;
    const auto mid = zv.begin() + static_cast<std::ptrdiff_t>(zv.size() / 2);
    std::nth_element(zv.begin(), mid, zv.end());
    const double median = *mid;
    if (median <= heights[v] - options_.min_drop_m) out[v] = median;
  }
  return out;
}

Eigen::VectorXd FarGroundSeeds::ceilings(const GroundGrid& grid, const Eigen::Vector3d& camera,
                                         const std::vector<Eigen::Vector3d>& points) const {
  const int n = grid.vertexCount();
  Eigen::VectorXd out = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::infinity());
  const double s = grid.resolution_m;
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) continue;
    const Eigen::Vector3d d = options_.ray_share * (p - camera);
    const double len_xy = d.head<2>().norm();
    const int steps = static_cast<int>(std::ceil(len_xy / (0.5 * s)));
    for (int k = 1; k <= steps; ++k) {
      const Eigen::Vector3d q = camera + (static_cast<double>(k) / steps) * d;
      const int c = static_cast<int>(std::lround((q.x() - grid.x0()) / s));
      const int r = static_cast<int>(std::lround((q.y() - grid.y0()) / s));
      if (!grid.contains(r, c)) continue;
      double& b = out[grid.index(r, c)];
      b = std::min(b, q.z());
    }
  }
  return out;
}

FarGroundStarts FarGroundSeeds::starts(const GroundGrid& grid, const Eigen::VectorXd& heights,
                                       const Eigen::VectorXd& information, const Eigen::Vector3d& camera,
                                       const std::vector<Eigen::Vector3d>& points) const {
  FarGroundStarts out;
  out.heights = seeds(grid, heights, information, points);
  out.ceilings = ceilings(grid, camera, points);
  const Eigen::VectorXd& ceiling = out.ceilings;
  for (int v = 0; v < grid.vertexCount(); ++v) {
    if (!std::isfinite(out.heights[v]) && heights[v] > ceiling[v] + options_.ceiling_margin_m) {
      out.heights[v] = ceiling[v];
      ++out.carved_vertices;
    }
  }
  out.seeded_vertices = static_cast<int>(out.heights.array().isFinite().count());
  return out;
}

}  // namespace stereo_ground_dem
