#include "stereo_ground_dem/DisparityPlaneFit.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

bool DisparityPlaneFitOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (ransac_iterations < 1 || min_inliers < 3) return bad("need ransac_iterations >= 1 and min_inliers >= 3");
  if (!(inlier_px > 0.0) || !(inlier_share >= 0.0) || !(min_disparity_px >= 0.0)) {
    return bad("need inlier_px > 0, inlier_share >= 0, min_disparity_px >= 0");
  }
  if (!(min_height_m > 0.0) || !(max_height_m > min_height_m)) return bad("need 0 < min_height_m < max_height_m");
  if (!(max_tilt_rad > 0.0 && max_tilt_rad < 1.5)) return bad("max_tilt_rad must be in (0, 1.5)");
  if (!expected_down.allFinite() || std::abs(expected_down.norm() - 1.0) > 1e-6) return bad("expected_down must be a unit vector");
  return true;
}

DisparityPlaneFitOptions DisparityPlaneFitOptions::nearAttitude(const Eigen::Vector3d& down, double max_tilt) const {
  DisparityPlaneFitOptions o = *this;
  if (!(down.norm() > 0.0) || !down.allFinite()) return o;
  o.expected_down = down.normalized();
  if (max_tilt > 0.0 && max_tilt < max_tilt_rad) o.max_tilt_rad = max_tilt;
  return o;
}

DisparityPlaneFit::DisparityPlaneFit(const DisparityPlaneFitOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("DisparityPlaneFitOptions: " + why);
}

DisparityPlane DisparityPlaneFit::fit(const std::vector<Eigen::Vector3f>& points, const StereoRig& rig) const {
  const DisparityPlaneFitOptions& o = options_;
  DisparityPlane out;
  std::vector<Eigen::Vector3d> p;  // (u, v, d) below the principal point's row, near enough
  for (const auto& q : points) {
    if (q.z() >= o.min_disparity_px && q.y() > rig.cy) p.emplace_back(q.x(), q.y(), q.z());
  }
  if (static_cast<int>(p.size()) < o.min_inliers) {
    out.message = "too few matches below the horizon (" + std::to_string(p.size()) + ")";
    return out;
  }
  // plane (a, b, c) -> camera plane: inverse depth rho = d / (fx b) = n . xhat / h with
  // xhat = K^-1 (u, v, 1): n / h = (a fx, b fy, a cx + b cy + c) / (fx b_m)
  auto toCamera = [&](const Eigen::Vector3d& abc, Eigen::Vector3d* down, double* h) {
    const Eigen::Vector3d m(abc[0] * rig.fx, abc[1] * rig.fy, abc[0] * rig.cx + abc[1] * rig.cy + abc[2]);
    const Eigen::Vector3d nh = m / (rig.fx * rig.baseline_m);
    const double norm = nh.norm();
    if (!(norm > 0.0)) return false;
    *down = nh / norm;
    *h = 1.0 / norm;
    return std::isfinite(*h) && *h >= o.min_height_m && *h <= o.max_height_m &&
           std::acos(std::clamp(down->dot(o.expected_down), -1.0, 1.0)) <= o.max_tilt_rad;
  };
  auto tolerance = [&](double d) { return o.inlier_px + o.inlier_share * d; };
  std::mt19937 rng(o.seed);
  std::uniform_int_distribution<size_t> pick(0, p.size() - 1);
  Eigen::Vector3d best_abc = Eigen::Vector3d::Zero();
  int best_count = 0;
  for (int it = 0; it < o.ransac_iterations; ++it) {
    const size_t i = pick(rng), j = pick(rng), k = pick(rng);
    Eigen::Matrix3d a;
    a << p[i].x(), p[i].y(), 1.0, p[j].x(), p[j].y(), 1.0, p[k].x(), p[k].y(), 1.0;
    if (std::abs(a.determinant()) < 1e-3) continue;
    const Eigen::Vector3d abc = a.inverse() * Eigen::Vector3d(p[i].z(), p[j].z(), p[k].z());
    Eigen::Vector3d down;
    double h = 0.0;
    if (!toCamera(abc, &down, &h)) continue;
    int count = 0;
    for (const auto& q : p) count += std::abs(abc[0] * q.x() + abc[1] * q.y() + abc[2] - q.z()) <= tolerance(q.z());
    if (count > best_count) {
      best_count = count;
      best_abc = abc;
    }
  }
  if (best_count < o.min_inliers) {
    std::ostringstream os;
    os << "no ground plane among the matches (" << best_count << " inliers at best; planes " << o.min_height_m << "-"
       << o.max_height_m << " m below the camera, tilted at most " << o.max_tilt_rad * 180.0 / M_PI
       << " deg from the expected ground)";
    out.message = os.str();
    return out;
  }
  // least squares on the inliers, twice
  Eigen::Vector3d abc = best_abc;
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    int n = 0;
    double ss = 0.0;
    for (const auto& q : p) {
      const double r = abc[0] * q.x() + abc[1] * q.y() + abc[2] - q.z();
      if (std::abs(r) > tolerance(q.z())) continue;
      const Eigen::Vector3d row(q.x(), q.y(), 1.0);
      ata += row * row.transpose();
      atb += row * q.z();
      ss += r * r;
      ++n;
    }
    if (n < o.min_inliers) break;
    abc = ata.ldlt().solve(atb);
    out.inliers = n;
    out.rms_px = std::sqrt(ss / n);
  }
  if (!toCamera(abc, &out.down, &out.height_m)) {
    out.message = "the fitted plane is not a plausible ground";
    return out;
  }
  out.ok = true;
  return out;
}

}  // namespace stereo_ground_dem
