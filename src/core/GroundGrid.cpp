#include "stereo_ground_dem/GroundGrid.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace stereo_ground_dem {

namespace {
int floorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int floorTo(int a, int m) { return floorDiv(a, m) * m; }
int ceilTo(int a, int m) { return -floorTo(-a, m); }
}  // namespace

GroundGrid GroundGrid::covering(double x_min, double x_max, double y_min, double y_max,
                                double resolution_m, int align) {
  if (!(resolution_m > 0.0) || align < 1 || !(x_max >= x_min) || !(y_max >= y_min)) {
    throw std::invalid_argument("GroundGrid::covering: invalid extent, resolution or alignment");
  }
  // Lattice indices and extents must stay far inside int (and the vertex count inside
  // kMaxVertices): check in double before converting.
  const double c_lo = std::floor(x_min / resolution_m), c_hi = std::ceil(x_max / resolution_m);
  const double r_lo = std::floor(y_min / resolution_m), r_hi = std::ceil(y_max / resolution_m);
  const double index_limit = static_cast<double>(kMaxLatticeIndex);
  const double count = (c_hi - c_lo + align + 1.0) * (r_hi - r_lo + align + 1.0);
  if (!(std::abs(c_lo) <= index_limit && std::abs(c_hi) <= index_limit && std::abs(r_lo) <= index_limit &&
        std::abs(r_hi) <= index_limit) ||
      align > kMaxLatticeIndex || !(count <= static_cast<double>(kMaxVertices))) {
    std::ostringstream os;
    os << "GroundGrid::covering: extent x [" << x_min << ", " << x_max << "] y [" << y_min << ", " << y_max
       << "] m at " << resolution_m << " m (align " << align << ") is out of range: lattice indices must be within +-"
       << kMaxLatticeIndex << " and the grid at most " << kMaxVertices << " vertices";
    throw std::invalid_argument(os.str());
  }
  GroundGrid g;
  g.resolution_m = resolution_m;
  const int c0 = floorTo(static_cast<int>(c_lo), align);
  const int c1 = ceilTo(static_cast<int>(c_hi), align);
  const int r0 = floorTo(static_cast<int>(r_lo), align);
  const int r1 = ceilTo(static_cast<int>(r_hi), align);
  g.col0 = c0;
  g.row0 = r0;
  g.cols = std::max(c1 - c0, align) + 1;
  g.rows = std::max(r1 - r0, align) + 1;
  return g;
}

std::array<int, 3> GroundGrid::triangle(int t) const {
  const int q = t >> 1;
  const int r = q / (cols - 1);
  const int c = q % (cols - 1);
  const int v00 = index(r, c);
  const int v11 = v00 + cols + 1;
  if ((t & 1) == 0) return {v00, v00 + 1, v11};
  return {v00, v11, v00 + cols};
}

bool GroundGrid::isCoarsenableBy(int factor) const {
  if (factor < 1) return false;
  return row0 % factor == 0 && col0 % factor == 0 && (rows - 1) % factor == 0 &&
         (cols - 1) % factor == 0 && rows > factor && cols > factor;
}

GroundGrid GroundGrid::coarsened(int factor) const {
  if (!isCoarsenableBy(factor)) {
    throw std::invalid_argument("GroundGrid::coarsened: grid is not aligned to the factor");
  }
  GroundGrid g;
  g.resolution_m = resolution_m * factor;
  g.row0 = row0 / factor;
  g.col0 = col0 / factor;
  g.rows = (rows - 1) / factor + 1;
  g.cols = (cols - 1) / factor + 1;
  return g;
}

Eigen::SparseMatrix<double, Eigen::RowMajor> GroundGrid::prolongationFrom(
    const GroundGrid& coarse) const {
  const double ratio = coarse.resolution_m / resolution_m;
  const int f = static_cast<int>(std::lround(ratio));
  if (f < 1 || std::abs(ratio - f) > 1e-9 || !isCoarsenableBy(f) ||
      !coarsened(f).sameLayout(coarse)) {
    throw std::invalid_argument("GroundGrid::prolongationFrom: grids are not nested");
  }
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(vertexCount()) * 3);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int v = index(r, c);
      int rc = r / f, cc = c / f;
      int dr = r % f, dc = c % f;
      if (rc == coarse.rows - 1 && dr == 0 && rc > 0) {
        rc -= 1;
        dr = f;
      }
      if (cc == coarse.cols - 1 && dc == 0 && cc > 0) {
        cc -= 1;
        dc = f;
      }
      const double y = static_cast<double>(dr) / f;  // local coordinates in the coarse square
      const double x = static_cast<double>(dc) / f;
      const int c00 = coarse.index(rc, cc);
      auto add = [&](int cv, double w) {
        if (w != 0.0) trip.emplace_back(v, cv, w);
      };
      if (dr == 0 && dc == 0) {
        add(c00, 1.0);
        continue;
      }
      const int c11 = coarse.index(rc + 1, cc + 1);
      if (y <= x) {  // triangle (00, 01, 11)
        add(c00, 1.0 - x);
        add(coarse.index(rc, cc + 1), x - y);
        add(c11, y);
      } else {  // triangle (00, 11, 10)
        add(c00, 1.0 - y);
        add(coarse.index(rc + 1, cc), y - x);
        add(c11, x);
      }
    }
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> p(vertexCount(), coarse.vertexCount());
  p.setFromTriplets(trip.begin(), trip.end());
  return p;
}

double GroundGrid::interpolate(const Eigen::VectorXd& z, double x, double y) const {
  const double fx = x / resolution_m - col0;
  const double fy = y / resolution_m - row0;
  if (!(fx >= 0.0 && fy >= 0.0 && fx <= cols - 1 && fy <= rows - 1)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  int c = std::min(static_cast<int>(fx), cols - 2);
  int r = std::min(static_cast<int>(fy), rows - 2);
  const double lx = fx - c, ly = fy - r;
  const double z00 = z[index(r, c)], z11 = z[index(r + 1, c + 1)];
  if (ly <= lx) return (1.0 - lx) * z00 + (lx - ly) * z[index(r, c + 1)] + ly * z11;
  return (1.0 - ly) * z00 + (ly - lx) * z[index(r + 1, c)] + lx * z11;
}

}  // namespace stereo_ground_dem
