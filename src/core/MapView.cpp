#include "stereo_ground_dem/MapView.hpp"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

namespace stereo_ground_dem {

namespace {
constexpr double kStartPull = 1e-6;  ///< the converged extension's pull to its start (vs neighbours' 1)
}  // namespace

GroundGrid MapView::window(const Eigen::Isometry3d& camera_T_ground) const {
  const StereoEstimatorOptions& s = stereo_;
  const Eigen::Isometry3d g_T_c = camera_T_ground.inverse();
  const double half_w = std::max(rig_.cx, rig_.width - 1 - rig_.cx) / rig_.fx;
  double xmin = 1e30, xmax = -1e30, ymin = 1e30, ymax = -1e30;
  for (double z : {s.min_range_m, s.max_range_m}) {
    const double lat = std::min(s.max_lateral_m, z * half_w);
    for (double x : {-lat, 0.0, lat}) {
      for (double y : {0.0, s.nominal_height_m}) {
        const Eigen::Vector3d g = g_T_c * Eigen::Vector3d(x, y, z);
        xmin = std::min(xmin, g.x());
        xmax = std::max(xmax, g.x());
        ymin = std::min(ymin, g.y());
        ymax = std::max(ymax, g.y());
      }
    }
  }
  const double margin = 2.0;
  return GroundGrid::covering(xmin - margin, xmax + margin, ymin - margin, ymax + margin, s.grid_resolution_m,
                              1 << (s.mesh_levels - 1));
}

void MapView::initialHeights(const GroundGrid& w, const Eigen::Isometry3d& camera_T_ground, Eigen::VectorXd* heights,
                             Eigen::VectorXd* information, const Eigen::VectorXd* seeds,
                             bool converged_with_seeds) const {
  map_.sample(w, heights, information);
  // Weakly known heights (seen by a few pixels at long range) are not trusted as a start: a vertex
  // that starts far too low hides behind its neighbours and never gets the pixels to correct it.
  const double min_info = 1.0 / (max_init_std_m_ * max_init_std_m_);
  int known = 0, n_seeded = 0;
  for (int v = 0; v < w.vertexCount(); ++v) {
    const bool seeded = seeds != nullptr && seeds->size() == w.vertexCount() && std::isfinite((*seeds)[v]);
    if (!std::isfinite((*heights)[v]) || (*information)[v] < min_info || seeded) {
      (*heights)[v] = seeded ? (*seeds)[v] : std::numeric_limits<double>::quiet_NaN();
      (*information)[v] = 0.0;
      known += seeded ? 1 : 0;
      n_seeded += seeded ? 1 : 0;
    } else {
      ++known;
    }
  }
  if (known == w.vertexCount()) return;
  // Extend the surface: start from a plane fitted to the known heights (or the level plane under
  // the camera), then relax the unknown heights to the harmonic extension of the known ones
  // (each the mean of its neighbours; exact for planes), so that a hill or a dip continues.
  Eigen::Vector3d pqc(0.0, 0.0, camera_T_ground.inverse().translation().z() - stereo_.nominal_height_m);
  if (known >= 20) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    for (int v = 0; v < w.vertexCount(); ++v) {
      if (!std::isfinite((*heights)[v])) continue;
      const Eigen::Vector2d xy = w.position(v);
      const Eigen::Vector3d a(xy.x(), xy.y(), 1.0);
      const double wt = std::min((*information)[v], 1e4) + 1.0;
      ata += wt * a * a.transpose();
      atb += wt * a * (*heights)[v];
    }
    if (ata.determinant() > 1e-9 * std::pow(ata.trace(), 3)) pqc = ata.ldlt().solve(atb);
  }
  std::vector<int> todo;
  for (int v = 0; v < w.vertexCount(); ++v) {
    if (std::isfinite((*heights)[v])) continue;
    const Eigen::Vector2d xy = w.position(v);
    (*heights)[v] = pqc.x() * xy.x() + pqc.y() * xy.y() + pqc.z();
    todo.push_back(v);
  }
  if (known < 20) return;
  // Gauss-Seidel sweeps over the unknown vertices, each the mean of its (up to four) neighbours,
  // whose indices are looked up once.
  std::vector<std::array<int, 4>> neighbours(todo.size());
  for (size_t i = 0; i < todo.size(); ++i) {
    const int r = w.rowOf(todo[i]), c = w.colOf(todo[i]);
    int n = 0;
    neighbours[i].fill(-1);
    for (const auto& d : {std::make_pair(0, 1), std::make_pair(0, -1), std::make_pair(1, 0), std::make_pair(-1, 0)}) {
      if (w.contains(r + d.first, c + d.second)) neighbours[i][static_cast<size_t>(n++)] = w.index(r + d.first, c + d.second);
    }
  }
  double* h = heights->data();
  if (n_seeded > 0 && converged_with_seeds) {
    // With seeds, the converged extension: the band between them and the known ground, 60 sweeps
    // leave ~40 % short of it (high enough to hide the far side it leads to). Its fixed point,
    // n_i h_i - sum of the unknown neighbours = sum of the known ones, solved by sparse Cholesky;
    // a tiny pull to the start keeps a patch without known neighbours determined.
    std::vector<int> slot(static_cast<size_t>(w.vertexCount()), -1);
    for (size_t i = 0; i < todo.size(); ++i) slot[static_cast<size_t>(todo[i])] = static_cast<int>(i);
    std::vector<Eigen::Triplet<double>> entries;
    Eigen::VectorXd rhs(static_cast<Eigen::Index>(todo.size()));
    for (size_t i = 0; i < todo.size(); ++i) {
      const std::array<int, 4>& nb = neighbours[i];
      int n = 0;
      double known_sum = 0.0;
      for (int k = 0; k < 4 && nb[static_cast<size_t>(k)] >= 0; ++k, ++n) {
        const int j = slot[static_cast<size_t>(nb[static_cast<size_t>(k)])];
        if (j >= 0) entries.emplace_back(static_cast<int>(i), j, -1.0);
        else known_sum += h[nb[static_cast<size_t>(k)]];
      }
      entries.emplace_back(static_cast<int>(i), static_cast<int>(i), n + kStartPull);
      rhs[static_cast<Eigen::Index>(i)] = known_sum + kStartPull * h[todo[i]];
    }
    Eigen::SparseMatrix<double> a(static_cast<Eigen::Index>(todo.size()), static_cast<Eigen::Index>(todo.size()));
    a.setFromTriplets(entries.begin(), entries.end());
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(a);
    if (ldlt.info() == Eigen::Success) {
      const Eigen::VectorXd x = ldlt.solve(rhs);
      if (x.allFinite()) {
        for (size_t i = 0; i < todo.size(); ++i) h[todo[i]] = x[static_cast<Eigen::Index>(i)];
        return;
      }
    }
  }
  for (int sweep = 0; sweep < 60; ++sweep) {
    for (size_t i = 0; i < todo.size(); ++i) {
      const std::array<int, 4>& nb = neighbours[i];
      double sum = 0.0;
      int n = 0;
      for (int k = 0; k < 4 && nb[static_cast<size_t>(k)] >= 0; ++k, ++n) sum += h[nb[static_cast<size_t>(k)]];
      if (n > 0) h[todo[i]] = sum / n;
    }
  }
}

bool MapView::groundAnchoredPose(const StereoPairCheck& check, const Eigen::Isometry3d& guess, Eigen::Isometry3d* out) const {
  const DisparityPlane plane = DisparityPlaneFit(stereo_.nearNominalAttitude(ground_plane_)).fit(check.points, rig_);
  if (!plane.ok) return false;
  // The map's plane z = p x + q y + c where the matched ground is: 4-15 m ahead of the guess.
  const Eigen::Isometry3d g_T_c = guess.inverse();
  Eigen::Vector3d fwd = g_T_c.linear().col(2);
  fwd.z() = 0.0;
  if (fwd.norm() < 1e-6) return false;
  fwd.normalize();
  const Eigen::Vector3d left(-fwd.y(), fwd.x(), 0.0);
  const Eigen::Vector3d c0 = g_T_c.translation();
  double xmin = 1e30, xmax = -1e30, ymin = 1e30, ymax = -1e30;
  for (double a : {4.0, 15.0})
    for (double b : {-6.0, 6.0}) {
      const Eigen::Vector3d q = c0 + a * fwd + b * left;
      xmin = std::min(xmin, q.x());
      xmax = std::max(xmax, q.x());
      ymin = std::min(ymin, q.y());
      ymax = std::max(ymax, q.y());
    }
  const GroundGrid w = GroundGrid::covering(xmin, xmax, ymin, ymax, stereo_.grid_resolution_m);
  Eigen::VectorXd h, info;
  map_.sample(w, &h, &info);
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  int known = 0;
  for (int v = 0; v < w.vertexCount(); ++v) {
    if (!std::isfinite(h[v])) continue;
    const Eigen::Vector2d xy = w.position(v);
    const Eigen::Vector2d rel = xy - c0.head<2>();
    const double along = rel.dot(fwd.head<2>()), across = rel.dot(left.head<2>());
    if (along < 4.0 || along > 15.0 || std::abs(across) > 6.0) continue;
    const Eigen::Vector3d a(xy.x(), xy.y(), 1.0);
    const double wt = std::min(info[v], 1e4) + 1.0;
    ata += wt * a * a.transpose();
    atb += wt * a * h[v];
    ++known;
  }
  Eigen::Vector3d pqc(0.0, 0.0, c0.z() - plane.height_m);  // level, through the guess' ground
  if (known >= 20 && ata.determinant() > 1e-9 * std::pow(ata.trace(), 3)) pqc = ata.ldlt().solve(atb);
  const Eigen::Vector3d up_unnormalized(-pqc.x(), -pqc.y(), 1.0);
  const Eigen::Vector3d up_g = up_unnormalized.normalized();
  // The smallest rotation of the guess that puts the map's up on the plane's up in the camera.
  const Eigen::Quaterniond corr = Eigen::Quaterniond::FromTwoVectors(guess.linear() * up_g, -plane.down);
  const Eigen::Matrix3d r = corr.toRotationMatrix() * guess.linear();
  // The camera centre over the guess' x, y at the plane's height above the map plane.
  Eigen::Vector3d c = c0;
  c.z() = pqc.x() * c.x() + pqc.y() * c.y() + pqc.z() + plane.height_m * up_unnormalized.norm();
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  t.translation() = -r * c;
  *out = t;
  return t.matrix().allFinite();
}

}  // namespace stereo_ground_dem
