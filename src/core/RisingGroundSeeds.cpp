#include "stereo_ground_dem/RisingGroundSeeds.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace stereo_ground_dem {

bool RisingGroundSeedsOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (min_points < 1) return bad("min_points must be >= 1");
  if (!(max_spread_m >= 0.0)) return bad("max_spread_m must be >= 0");
  if (!(min_rise_m >= 0.0)) return bad("min_rise_m must be >= 0");
  if (!(max_slope_deg > 0.0 && max_slope_deg < 90.0)) return bad("max_slope_deg must be in (0, 90)");
  if (min_region_vertices < 1) return bad("min_region_vertices must be >= 1");
  if (!(max_range_m > 0.0)) return bad("max_range_m must be > 0");
  return true;
}

RisingGroundSeeds::RisingGroundSeeds(const RisingGroundSeedsOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("RisingGroundSeedsOptions: " + why);
}

Eigen::VectorXd RisingGroundSeeds::seeds(const GroundGrid& grid, const Eigen::VectorXd& heights,
                                         const Eigen::VectorXd& information, const Eigen::Vector3d& camera,
                                         const std::vector<Eigen::Vector3d>& points) const {
  const int n = grid.vertexCount();
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  Eigen::VectorXd out = Eigen::VectorXd::Constant(n, kNaN);
  if (n == 0 || points.empty()) return out;
  // Each point counts for the (up to four) vertices of its grid cell, relative to the vertex.
  std::vector<std::vector<Eigen::Vector3d>> local(static_cast<size_t>(n));
  const double s = grid.resolution_m;
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite() || (p - camera).head<2>().norm() > options_.max_range_m) continue;
    grid.forCellVertices(p.x(), p.y(), [&](int v) {
      const Eigen::Vector2d xy = grid.position(v);
      local[static_cast<size_t>(v)].emplace_back(p.x() - xy.x(), p.y() - xy.y(), p.z());
    });
  }
  // Candidates: unknown vertices whose points lie on one plane (z = a + b dx + c dy, least
  // squares; or a line, below) no steeper than max_slope_deg, to a median |residual| of at most
  // max_spread_m, its height a at least min_rise_m above the hypothesis. An upright face's points
  // stack up at one place: no such plane (steep, or far off it).
  const double max_gradient = std::tan(options_.max_slope_deg * EIGEN_PI / 180.0);
  Eigen::VectorXd start = Eigen::VectorXd::Constant(n, kNaN);
  std::vector<double> res;
  for (int v = 0; v < n; ++v) {
    const std::vector<Eigen::Vector3d>& pv = local[static_cast<size_t>(v)];
    if (static_cast<int>(pv.size()) < options_.min_points || information[v] > 0.0) continue;
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& q : pv) {
      const Eigen::Vector3d row(1.0, q.x(), q.y());
      ata += row * row.transpose();
      atb += row * q.z();
    }
    // The points spread over the support in two directions (rms an eighth of a spacing across):
    // a plane. In one only (a window's disparity is whole pixels at the test level, so the points
    // of one depth step lie near a line across the view): a line, z = a + g t along it, level
    // across it. At one place: no surface.
    const double m = static_cast<double>(pv.size());
    const Eigen::Vector2d mean_xy = ata.block<2, 1>(1, 0) / m;
    const Eigen::Matrix2d cov = ata.bottomRightCorner<2, 2>() / m - mean_xy * mean_xy.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    const double min_var = 0.015625 * s * s;
    if (eig.eigenvalues()[1] < min_var) continue;
    Eigen::Vector3d abc;
    if (eig.eigenvalues()[0] >= min_var) {
      abc = ata.ldlt().solve(atb);
    } else {
      const Eigen::Vector2d dir = eig.eigenvectors().col(1);
      Eigen::Matrix2d a2 = Eigen::Matrix2d::Zero();
      Eigen::Vector2d b2 = Eigen::Vector2d::Zero();
      for (const Eigen::Vector3d& q : pv) {
        const Eigen::Vector2d row(1.0, dir.dot(q.head<2>()));
        a2 += row * row.transpose();
        b2 += row * q.z();
      }
      const Eigen::Vector2d ag = a2.ldlt().solve(b2);
      abc << ag[0], ag[1] * dir;
    }
    if (!abc.allFinite() || abc.tail<2>().norm() > max_gradient) continue;
    res.clear();
    for (const Eigen::Vector3d& q : pv) res.push_back(std::abs(q.z() - abc[0] - abc[1] * q.x() - abc[2] * q.y()));
    std::nth_element(res.begin(), res.begin() + static_cast<std::ptrdiff_t>(res.size() / 2), res.end());
    if (res[res.size() / 2] > options_.max_spread_m || abc[0] < heights[v] + options_.min_rise_m) continue;
    start[v] = abc[0];
  }
  // Grow from the surface's ground (no candidate, fewer than min_points points: the pixels there
  // fit the hypothesis), breadth first
  // over the 4-neighbourhood, each step no steeper than max_slope_deg; regions (the vertices
  // reached from one entry) of at least min_region_vertices.
  const double max_step = max_gradient * s;
  std::vector<int> region(static_cast<size_t>(n), -1);
  std::vector<int> queue;
  std::vector<int> region_size;
  const int dr[4] = {0, 0, 1, -1}, dc[4] = {1, -1, 0, 0};
  for (int v = 0; v < n; ++v) {
    if (!std::isfinite(start[v]) || region[static_cast<size_t>(v)] >= 0) continue;
    // an entry: next to the surface's ground, no steeper than the limit
    const int r = grid.rowOf(v), c = grid.colOf(v);
    bool entry = false;
    for (int k = 0; k < 4 && !entry; ++k) {
      if (!grid.contains(r + dr[k], c + dc[k])) continue;
      const int u = grid.index(r + dr[k], c + dc[k]);
      entry = !std::isfinite(start[u]) && static_cast<int>(local[static_cast<size_t>(u)].size()) < options_.min_points &&
              std::abs(start[v] - heights[u]) <= max_step;
    }
    if (!entry) continue;
    const int id = static_cast<int>(region_size.size());
    region_size.push_back(0);
    queue.assign(1, v);
    region[static_cast<size_t>(v)] = id;
    for (size_t qi = 0; qi < queue.size(); ++qi) {
      const int a = queue[qi];
      ++region_size.back();
      const int ra = grid.rowOf(a), ca = grid.colOf(a);
      for (int k = 0; k < 4; ++k) {
        if (!grid.contains(ra + dr[k], ca + dc[k])) continue;
        const int b = grid.index(ra + dr[k], ca + dc[k]);
        if (!std::isfinite(start[b]) || region[static_cast<size_t>(b)] >= 0) continue;
        if (std::abs(start[b] - start[a]) > max_step) continue;
        region[static_cast<size_t>(b)] = id;
        queue.push_back(b);
      }
    }
  }
  for (int v = 0; v < n; ++v) {
    const int id = region[static_cast<size_t>(v)];
    if (id >= 0 && region_size[static_cast<size_t>(id)] >= options_.min_region_vertices) out[v] = start[v];
  }
  return out;
}

}  // namespace stereo_ground_dem
