#include "stereo_ground_dem/GroundAttitudeEstimator.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <vector>

namespace stereo_ground_dem {

namespace {
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

/// Least-squares plane z = a x + b y + c through the points (x, y, z) with use[i] set; false when
/// fewer than `min_points` or the points are (nearly) collinear.
bool fitPlane(const std::vector<Eigen::Vector3d>& p, const std::vector<bool>& use, int min_points, Eigen::Vector3d* abc) {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  int n = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    if (!use[i]) continue;
    const Eigen::Vector3d row(p[i].x(), p[i].y(), 1.0);
    ata += row * row.transpose();
    atb += row * p[i].z();
    ++n;
  }
  if (n < min_points) return false;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || ldlt.vectorD().minCoeff() < 1e-9 * ata.trace()) return false;
  *abc = ldlt.solve(atb);
  return abc->allFinite();
}
}  // namespace

GroundAttitudeEstimate::GroundAttitudeEstimate()
    : height_m(kNan), pitch_rad(kNan), roll_rad(kNan), slope_rad(kNan), rms_m(kNan) {}

bool GroundAttitudeOptions::isValid(std::string* why) const {
  auto bad = [&](const char* w) {
    if (why) *why = w;
    return false;
  };
  if (!(radius_m > 0.0 && radius_m < 1e4)) return bad("radius_m must be in (0, 1e4)");
  if (!(min_coverage > 0.0 && min_coverage <= 1.0)) return bad("min_coverage must be in (0, 1]");
  if (!(outlier_m > 0.0)) return bad("outlier_m must be > 0");
  if (!(mount_height_tolerance_m > 0.0) || !(mount_angle_tolerance_rad > 0.0)) {
    return bad("mount_height_tolerance_m and mount_angle_tolerance_rad must be > 0");
  }
  if (mount_min_estimates < 1) return bad("mount_min_estimates must be >= 1");
  return true;
}

GroundAttitudeEstimator::GroundAttitudeEstimator(const GroundAttitudeOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("GroundAttitudeOptions: " + why);
}

GroundAttitudeEstimate GroundAttitudeEstimator::relativeToPlane(const Eigen::Vector3d& abc, const Eigen::Isometry3d& ground_T_camera) {
  GroundAttitudeEstimate e;
  const Eigen::Vector3d n = Eigen::Vector3d(-abc.x(), -abc.y(), 1.0).normalized();  // up
  const Eigen::Vector3d p = ground_T_camera.translation();
  const Eigen::Matrix3d& r = ground_T_camera.linear();
  const Eigen::Vector3d forward = r.col(2), left = -r.col(0), up = -r.col(1);
  e.height_m = (p.z() - (abc.x() * p.x() + abc.y() * p.y() + abc.z())) * n.z();
  e.pitch_rad = std::asin(std::clamp(-n.dot(forward), -1.0, 1.0));
  e.roll_rad = std::atan2(n.dot(left), n.dot(up));  // Z-Y-X Euler angles relative to the plane
  e.slope_rad = std::acos(std::clamp(n.z(), -1.0, 1.0));
  e.valid = true;
  return e;
}

GroundAttitudeEstimate GroundAttitudeEstimator::estimate(const ElevationMap& map, const Eigen::Isometry3d& ground_T_camera) const {
  const Eigen::Vector3d c = ground_T_camera.translation();
  GroundAttitudeEstimate none;
  if (!ground_T_camera.matrix().allFinite()) return none;
  const double r = options_.radius_m;
  const GroundGrid window =
      GroundGrid::covering(c.x() - r, c.x() + r, c.y() - r, c.y() + r, map.options().resolution_m);
  const cv::Mat z = map.layer(ElevationMap::Layer::kElevation, window);
  const cv::Mat obstacle = map.layer(ElevationMap::Layer::kObstacle, window);
  std::vector<Eigen::Vector3d> pts;
  int disc = 0;
  for (int row = 0; row < window.rows; ++row) {
    for (int col = 0; col < window.cols; ++col) {
      const double x = window.xOfCol(col), y = window.yOfRow(row);
      if ((x - c.x()) * (x - c.x()) + (y - c.y()) * (y - c.y()) > r * r) continue;
      ++disc;
      const float h = z.at<float>(row, col);
      if (!std::isfinite(h) || obstacle.at<float>(row, col) > 0.5f) continue;  // unknown or under an obstacle
      pts.emplace_back(x, y, h);
    }
  }
  const int min_points = std::max(3, static_cast<int>(std::ceil(options_.min_coverage * disc)));
  std::vector<bool> use(pts.size(), true);
  Eigen::Vector3d abc;
  if (!fitPlane(pts, use, min_points, &abc)) return none;
  // Once more without what the plane does not explain (a curb, a rut, a stone); when that is
  // more than half of it, the ground there is no plane.
  for (size_t i = 0; i < pts.size(); ++i) {
    use[i] = std::abs(pts[i].z() - (abc.x() * pts[i].x() + abc.y() * pts[i].y() + abc.z())) <= options_.outlier_m;
  }
  if (!fitPlane(pts, use, std::max(3, static_cast<int>(pts.size() / 2)), &abc)) return none;
  GroundAttitudeEstimate e = relativeToPlane(abc, ground_T_camera);
  double ss = 0.0;
  e.vertices = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (!use[i]) continue;
    const double d = pts[i].z() - (abc.x() * pts[i].x() + abc.y() * pts[i].y() + abc.z());
    ss += d * d;
    ++e.vertices;
  }
  e.rms_m = std::sqrt(ss / e.vertices);
  return e;
}

std::string GroundAttitudeEstimator::mountWarning(const std::vector<GroundAttitudeEstimate>& recent,
                                         const GroundAttitudeEstimate& nominal) const {
  std::vector<double> h, p, r;
  for (const auto& e : recent) {
    if (!e.valid) continue;
    h.push_back(e.height_m);
    p.push_back(e.pitch_rad);
    r.push_back(e.roll_rad);
  }
  if (static_cast<int>(h.size()) < options_.mount_min_estimates) return "";
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double mh = median(h), mp = median(p), mr = median(r);
  constexpr double kDeg = 180.0 / M_PI;
  char buf[320];
  if (std::abs(mh - nominal.height_m) > options_.mount_height_tolerance_m ||
      std::abs(mp - nominal.pitch_rad) > options_.mount_angle_tolerance_rad ||
      std::abs(mr - nominal.roll_rad) > options_.mount_angle_tolerance_rad) {
    std::snprintf(buf, sizeof(buf),
                  "the camera sits on the ground unlike its nominal mount (median of the last %zu frames: height "
                  "%.2f m, pitch %.1f deg, roll %.1f deg; nominal %.2f m, %.1f deg, %.1f deg): a moved mount, wrong "
                  "nominal_* parameters, or a drifting estimate",
                  h.size(), mh, mp * kDeg, mr * kDeg, nominal.height_m, nominal.pitch_rad * kDeg, nominal.roll_rad * kDeg);
    return buf;
  }
  return "";
}

}  // namespace stereo_ground_dem
