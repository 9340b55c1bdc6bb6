#pragma once
/// \file GroundGrid.hpp
/// A rectangular window of the regular ground lattice, and its triangulation.
///
/// Grid conventions (written once, used everywhere):
///  - ground frame G: right-handed, z up, x-y level; x points forward and y to the left of the
///    first camera (REP 103 axes), origin on the ground below the first camera [m];
///  - the lattice has spacing `resolution_m`; lattice vertex (i, j) sits at x = j * resolution_m,
///    y = i * resolution_m: the ROW index i runs along +y, the COLUMN index j along +x;
///  - a GroundGrid is the window of `rows` x `cols` vertices whose vertex (r, c) is lattice vertex
///    (row0 + r, col0 + c), i.e. x = x0 + c * resolution_m, y = y0 + r * resolution_m with
///    (x0, y0) = (col0, row0) * resolution_m, the "origin" written to dem.yaml;
///  - vertex (r, c) has the flat index r * cols + c (row-major);
///  - square (r, c) (lower corner (r, c), r < rows-1, c < cols-1) is split along its diagonal
///    (r, c)-(r+1, c+1) into triangle 2q: (r,c), (r,c+1), (r+1,c+1) and triangle 2q+1:
///    (r,c), (r+1,c+1), (r+1,c), with q = r * (cols-1) + c.
///
///        y (row) ^    (r+1,c) o-------o (r+1,c+1)
///                |            | 2q+1 /|
///                |            |    /  |
///                |            |  /  2q|
///                |     (r,c)  o-------o (r,c+1)
///                +------------------> x (col)
///
/// Because every level uses the same diagonal direction, the grid at spacing s refines the grid at
/// spacing 2s exactly: each coarse triangle is the union of four fine ones, and piecewise-linear
/// interpolation of coarse heights reproduces the coarse surface (see prolongationFrom()).

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>

namespace stereo_ground_dem {

struct GroundGrid {
  double resolution_m = 0.5;  ///< vertex spacing [m]
  int row0 = 0;               ///< lattice row (y) index of vertex (0, 0)
  int col0 = 0;               ///< lattice column (x) index of vertex (0, 0)
  int rows = 0;               ///< vertices along y
  int cols = 0;               ///< vertices along x

  /// Largest |lattice index| and vertex count covering() produces (int-safe with room to spare).
  static constexpr int kMaxLatticeIndex = 1 << 28;
  static constexpr int kMaxVertices = 1 << 28;

  /// The smallest grid on the lattice of spacing `resolution_m` covering [x_min, x_max] x
  /// [y_min, y_max] whose first index and extent are multiples of `align` (so that it can be
  /// coarsened by `align`). Throws std::invalid_argument for a non-finite or inverted extent, and,
  /// naming the numbers, for an extent beyond kMaxLatticeIndex or kMaxVertices.
  static GroundGrid covering(double x_min, double x_max, double y_min, double y_max,
                             double resolution_m, int align = 1);

  int vertexCount() const { return rows * cols; }
  int triangleCount() const { return rows > 1 && cols > 1 ? 2 * (rows - 1) * (cols - 1) : 0; }
  int index(int r, int c) const { return r * cols + c; }
  int rowOf(int v) const { return v / cols; }
  int colOf(int v) const { return v % cols; }
  double x0() const { return col0 * resolution_m; }
  double y0() const { return row0 * resolution_m; }
  double xOfCol(int c) const { return (col0 + c) * resolution_m; }
  double yOfRow(int r) const { return (row0 + r) * resolution_m; }
  Eigen::Vector2d position(int v) const { return {xOfCol(colOf(v)), yOfRow(rowOf(v))}; }
  bool contains(int r, int c) const { return r >= 0 && c >= 0 && r < rows && c < cols; }
  /// Calls f(v) for each vertex v of the cell holding ground point (x, y) (up to four: a point
  /// on the cell's far edge also counts for the next cell's vertices); nothing outside the grid.
  template <typename F>
  void forCellVertices(double x, double y, F&& f) const {
    const double fc = (x - x0()) / resolution_m, fr = (y - y0()) / resolution_m;
    if (!(fc >= 0.0 && fr >= 0.0 && fc <= cols - 1 && fr <= rows - 1)) return;
    const int c0 = static_cast<int>(fc), r0 = static_cast<int>(fr);
    for (int dr = 0; dr <= 1; ++dr)
      for (int dc = 0; dc <= 1; ++dc)
        if (contains(r0 + dr, c0 + dc)) f(index(r0 + dr, c0 + dc));
  }
  /// The three vertex indices of triangle t, in the order given in the file comment.
  std::array<int, 3> triangle(int t) const;

  /// Whether coarsened(factor) exists: first indices and extents divisible by `factor`.
  bool isCoarsenableBy(int factor) const;
  /// The grid of spacing factor * resolution_m made of every factor-th vertex.
  GroundGrid coarsened(int factor) const;

  /// The sparse (this->vertexCount() x coarse.vertexCount()) matrix P such that z_fine = P z_coarse
  /// is the piecewise-linear interpolation of the coarse mesh at the fine vertices. `coarse` must be
  /// this->coarsened(f) for some power of two f.
  Eigen::SparseMatrix<double, Eigen::RowMajor> prolongationFrom(const GroundGrid& coarse) const;

  /// Piecewise-linear height at ground point (x, y) of the mesh with vertex heights `z`; NaN outside
  /// the grid or where a vertex of the containing triangle is NaN.
  double interpolate(const Eigen::VectorXd& z, double x, double y) const;

  bool sameLayout(const GroundGrid& o) const {
    return resolution_m == o.resolution_m && row0 == o.row0 && col0 == o.col0 && rows == o.rows &&
           cols == o.cols;
  }
};

}  // namespace stereo_ground_dem
