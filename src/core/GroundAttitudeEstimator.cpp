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
  if (!(radius_m > 0.0 && radius_m <= 100.0)) return bad("radius_m must be in (0, 100]");
  if (!(min_coverage > 0.0 && min_coverage <= 1.0)) return bad("min_coverage must be in (0, 1]");
  if (!(outlier_m > 0.0)) return bad("outlier_m must be > 0");
  if (!(mount_height_tolerance_m > 0.0) || !(mount_angle_tolerance_rad > 0.0)) {
    return bad("mount_height_tolerance_m and mount_angle_tolerance_rad must be > 0");
  }
  if (mount_min_estimates < 1 || mount_min_estimates > mount_window_frames) {
    return bad("mount_min_estimates must be in 1..mount_window_frames");
  }
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
      pts.emplace_back(x - c.x(), y - c.y(), h);  // centred on the nadir: the fit is as good 5 km out
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
  // Back to G: z = a (x - cx) + b (y - cy) + c'.
  const Eigen::Vector3d abc_g(abc.x(), abc.y(), abc.z() - abc.x() * c.x() - abc.y() * c.y());
  GroundAttitudeEstimate e = relativeToPlane(abc_g, ground_T_camera);
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

GroundAttitudeEstimate GroundAttitudeEstimator::typical(const std::vector<GroundAttitudeEstimate>& estimates) const {
  std::vector<double> h, p, r;
  for (const auto& e : estimates) {
    if (!e.valid) continue;
    h.push_back(e.height_m);
    p.push_back(e.pitch_rad);
    r.push_back(e.roll_rad);
  }
  GroundAttitudeEstimate t;
  if (static_cast<int>(h.size()) < options_.mount_min_estimates) return t;
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  t.valid = true;
  t.height_m = median(h);
  t.pitch_rad = median(p);
  t.roll_rad = median(r);
  return t;
}

std::string GroundAttitudeEstimator::mountWarning(const std::vector<GroundAttitudeEstimate>& recent,
                                                  const GroundAttitudeEstimate& reference) const {
  const GroundAttitudeEstimate now = typical(recent);
  if (!now.valid || !reference.valid) return "";
  if (std::abs(now.height_m - reference.height_m) <= options_.mount_height_tolerance_m &&
      std::abs(now.pitch_rad - reference.pitch_rad) <= options_.mount_angle_tolerance_rad &&
      std::abs(now.roll_rad - reference.roll_rad) <= options_.mount_angle_tolerance_rad) {
    return "";
  }
  const long used = std::count_if(recent.begin(), recent.end(), [](const GroundAttitudeEstimate& e) { return e.valid; });
  constexpr double kDeg = 180.0 / M_PI;
  char buf[320];
  std::snprintf(buf, sizeof(buf),
                "the camera sits on the ground unlike at the start of the map (median of the last %ld frames: height "
                "%.2f m, pitch %.1f deg, roll %.1f deg; at the start %.2f m, %.1f deg, %.1f deg): a mount that moved, "
                "or a drifting estimate",
                used, now.height_m, now.pitch_rad * kDeg, now.roll_rad * kDeg, reference.height_m,
                reference.pitch_rad * kDeg, reference.roll_rad * kDeg);
  return buf;
}

}  // namespace stereo_ground_dem
