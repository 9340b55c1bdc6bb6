#include "stereo_ground_dem/SurfaceIncidence.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {

// dz/du at (r, c) along one lattice axis from the neighbours' heights `lo` (at -s) and `hi` (+s);
// NaN when neither side is finite.
double slope(double z0, double lo, double hi, double s) {
  const bool l = std::isfinite(lo), h = std::isfinite(hi);
  if (l && h) return (hi - lo) / (2.0 * s);
  if (h) return (hi - z0) / s;
  if (l) return (z0 - lo) / s;
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

Eigen::VectorXd SurfaceIncidence::ratios(const GroundGrid& grid, const Eigen::VectorXd& z,
                                         const Eigen::Vector3d& camera_centre_ground) {
  if (z.size() != grid.vertexCount()) throw std::invalid_argument("SurfaceIncidence: heights do not match the grid");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::VectorXd out = Eigen::VectorXd::Constant(grid.vertexCount(), nan);
  const double s = grid.resolution_m;
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const int v = grid.index(r, c);
      const double z0 = z[v];
      if (!std::isfinite(z0)) continue;
      const double dzdx = slope(z0, c > 0 ? z[v - 1] : nan, c + 1 < grid.cols ? z[v + 1] : nan, s);
      const double dzdy = slope(z0, r > 0 ? z[v - grid.cols] : nan, r + 1 < grid.rows ? z[v + grid.cols] : nan, s);
      if (!std::isfinite(dzdx) || !std::isfinite(dzdy)) continue;
      const Eigen::Vector3d p(grid.xOfCol(c), grid.yOfRow(r), z0);
      const Eigen::Vector3d d = (p - camera_centre_ground).normalized();
      const double cos_level = -d.z();
      if (!(cos_level > 0.0)) continue;
      const Eigen::Vector3d n = Eigen::Vector3d(-dzdx, -dzdy, 1.0).normalized();
      out[v] = -n.dot(d) / cos_level;
    }
  }
  return out;
}

}  // namespace stereo_ground_dem
