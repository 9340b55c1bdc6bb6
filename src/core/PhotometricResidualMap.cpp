#include "stereo_ground_dem/PhotometricResidualMap.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "stereo_ground_dem/ImagePyramid.hpp"

namespace stereo_ground_dem {

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();


/// Pixel of camera point p, false when outside [m, size - 1 - m] or not in front.
bool project(const StereoRig& rig, const Eigen::Vector3d& p, const cv::Mat& img, double margin, double* u, double* v) {
  if (!(p.z() > 1e-6)) return false;
  *u = rig.fx * p.x() / p.z() + rig.cx;
  *v = rig.fy * p.y() / p.z() + rig.cy;
  return *u >= margin && *v >= margin && *u <= img.cols - 1 - margin && *v <= img.rows - 1 - margin;
}
}  // namespace

bool PhotometricResidualOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (samples_per_cell < 1 || samples_per_cell > 16) return bad("samples_per_cell must be in 1..16");
  if (!(min_range_m > 0.0 && max_range_m > min_range_m && std::isfinite(max_range_m))) return bad("need 0 < min_range_m < max_range_m");
  if (!(update_weight > 0.0 && update_weight <= 1.0)) return bad("update_weight must be in (0, 1]");
  if (!(outlier_sigmas > 0.0 && std::isfinite(outlier_sigmas))) return bad("outlier_sigmas must be > 0");
  if (!(min_outlier_grey >= 0.0 && std::isfinite(min_outlier_grey))) return bad("min_outlier_grey must be >= 0");
  if (!(max_residual_grey > 0.0 && std::isfinite(max_residual_grey))) return bad("max_residual_grey must be > 0");
  if (min_points < 1) return bad("min_points must be >= 1");
  if (!(keep_radius_m > 0.0)) return bad("keep_radius_m must be > 0");
  if (tile_size < 8 || tile_size > 1024) return bad("tile_size must be in 8..1024");
  if (image_margin_px < 1 || image_margin_px > 1000) return bad("image_margin_px must be in 1..1000");
  if (!(dark_level_grey < saturated_level_grey)) return bad("need dark_level_grey < saturated_level_grey");
  if (!(max_published_outlier_rate > 0.0) || std::isnan(max_published_outlier_rate)) {
    return bad("max_published_outlier_rate must be > 0 (above 1: every height published)");
  }
  return true;
}

PhotometricResidualMap::Tile::Tile(size_t n) : residual(n, kNaN), outlier_rate(n, kNaN), observations(n, 0) {}

PhotometricResidualMap::PhotometricResidualMap(double resolution_m, const PhotometricResidualOptions& options)
    : options_(options),
      resolution_m_(resolution_m),
      tiles_(options.tile_size, resolution_m),
      last_median_(std::numeric_limits<double>::quiet_NaN()) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("PhotometricResidualOptions: " + why);
  if (!(resolution_m > 0.0)) throw std::invalid_argument("PhotometricResidualMap: resolution_m must be > 0");
}

int PhotometricResidualMap::update(const ElevationMap& map, const GroundGrid& window, const cv::Mat& left,
                                   const cv::Mat& right, const StereoRig& rig, const Eigen::Isometry3d& ground_T_camera,
                                   const VerticalMisalignment& rectification, const PhotometricParams& stereo,
                                   const PhotometricParams* temporal, const cv::Mat& obstacles,
                                   const cv::Mat& moving) {
  if (!options_.enabled) return 0;
  if (left.type() != CV_32FC1 || right.type() != CV_32FC1 || left.size() != right.size() || left.cols < 2 ||
      left.rows < 2) {
    throw std::invalid_argument("PhotometricResidualMap::update: left and right must be CV_32F grey of one size");
  }
  if (std::abs(window.resolution_m - resolution_m_) > 1e-9) {
    throw std::invalid_argument("PhotometricResidualMap::update: window resolution differs from the map's");
  }
  const bool with_previous = temporal && !previous_left_.empty() && previous_left_.size() == left.size();
  // The masks at their own level: a point's left pixel (u, v) is the mask's (u, v) * scale.
  auto maskScale = [&left](const cv::Mat& m, const char* name) {
    if (m.empty()) return 0.0;
    if (m.type() != CV_8UC1) throw std::invalid_argument(std::string("PhotometricResidualMap::update: ") + name + " must be CV_8U");
    for (int k = 0; k < 16; ++k) {
      if (m.cols == ((left.cols + (1 << k) - 1) >> k) && m.rows == ((left.rows + (1 << k) - 1) >> k)) return 1.0 / (1 << k);
    }
    throw std::invalid_argument(std::string("PhotometricResidualMap::update: ") + name +
                                " is not the left image's size at a pyramid level");
  };
  const double obstacle_scale = maskScale(obstacles, "obstacles"), moving_scale = maskScale(moving, "moving");
  auto isSet = [](const cv::Mat& m, double scale, double u, double v) {
    if (m.empty()) return false;
    const int c = std::min(m.cols - 1, static_cast<int>(u * scale + 0.5));
    const int r = std::min(m.rows - 1, static_cast<int>(v * scale + 0.5));
    return m.at<uint8_t>(r, c) != 0;
  };
  const Eigen::Isometry3d camera_T_ground = ground_T_camera.inverse();
  // The estimator's stereo geometry (StereoEstimator::rightTLeft, stereoTarget): the baseline, the
  // modelled y offset, and the row shift of the right image.
  const Eigen::Vector3d right_centre(rig.baseline_m, rectification.rightCameraOffsetY(rig), 0.0);
  const bool row_shift = rectification.hasRowShift();
  const float dark = static_cast<float>(options_.dark_level_grey), sat = static_cast<float>(options_.saturated_level_grey);
  auto usable = [dark, sat](float value) { return value > dark && value < sat; };
  const double margin = options_.image_margin_px, clamp = options_.max_residual_grey;
  const int n = options_.samples_per_cell;

  Eigen::VectorXd z, info;
  map.sample(window, &z, &info);
  // Per cell (a vertex of the window): the median over its points of the worse pair's |residual|.
  std::vector<float> cell(static_cast<size_t>(window.vertexCount()), kNaN);
  std::vector<float> values, point_residuals;
  values.reserve(cell.size());
  point_residuals.reserve(static_cast<size_t>(n * n));
  for (int v = 0; v < window.vertexCount(); ++v) {
    if (!std::isfinite(z[v])) continue;
    const Eigen::Vector2d xy = window.position(v);
    // Quick reject on the vertex itself (a cell is 0.5 m: the margin covers it).
    const Eigen::Vector3d pv = camera_T_ground * Eigen::Vector3d(xy.x(), xy.y(), z[v]);
    if (pv.z() < options_.min_range_m - window.resolution_m || pv.z() > options_.max_range_m + window.resolution_m) continue;
    point_residuals.clear();
    for (int a = 0; a < n; ++a) {
      const double y = xy.y() + ((a + 0.5) / n - 0.5) * window.resolution_m;
      for (int b = 0; b < n; ++b) {
        const double x = xy.x() + ((b + 0.5) / n - 0.5) * window.resolution_m;
        const double h = window.interpolate(z, x, y);
        if (!std::isfinite(h)) continue;
        const Eigen::Vector3d g(x, y, h);
        const Eigen::Vector3d pc = camera_T_ground * g;
        if (pc.z() < options_.min_range_m || pc.z() > options_.max_range_m) continue;
        double u = 0, w = 0, ur = 0, vr = 0;
        if (!project(rig, pc, left, margin, &u, &w) || !project(rig, pc - right_centre, right, margin, &ur, &vr)) continue;
        if (row_shift) {
          vr += rectification.rowShift(rig, ur, vr);
          if (!(vr >= margin && vr <= right.rows - 1 - margin)) continue;
        }
        if (isSet(obstacles, obstacle_scale, u, w)) continue;  // hidden this frame
        const float l = ImagePyramid::sampleBilinear(left, u, w), rv = ImagePyramid::sampleBilinear(right, ur, vr);
        if (!usable(l) || !usable(rv)) continue;
        const double e_s = std::abs(l - (stereo.gain * rv + stereo.bias_grey));
        if (!std::isfinite(e_s)) continue;
        double r = std::min(clamp, e_s);
        if (with_previous && !isSet(moving, moving_scale, u, w)) {
          double up = 0, vp = 0;
          if (project(rig, previous_camera_T_ground_ * g, previous_left_, margin, &up, &vp)) {
            const float pv = ImagePyramid::sampleBilinear(previous_left_, up, vp);
            const double e_t = std::abs(l - (temporal->gain * pv + temporal->bias_grey));
            if (usable(pv) && std::isfinite(e_t)) r = std::max(r, std::min(clamp, e_t));
          }
        }
        point_residuals.push_back(static_cast<float>(r));
      }
    }
    if (static_cast<int>(point_residuals.size()) < options_.min_points) continue;
    // The median: an image edge a pixel off (a lane line's border) spoils a few points, an object
    // that the surface does not explain most of them.
    auto mid = point_residuals.begin() + static_cast<long>(point_residuals.size() / 2);
    std::nth_element(point_residuals.begin(), mid, point_residuals.end());
    cell[static_cast<size_t>(v)] = *mid;
    values.push_back(cell[static_cast<size_t>(v)]);
  }

  int updated = 0;
  if (!values.empty()) {
    std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
    last_median_ = values[values.size() / 2];
    const double threshold = std::max(options_.outlier_sigmas * 1.4826 * last_median_, options_.min_outlier_grey);
    const float w = static_cast<float>(options_.update_weight);
    for (int v = 0; v < window.vertexCount(); ++v) {
      const float res = cell[static_cast<size_t>(v)];
      if (!std::isfinite(res)) continue;
      size_t k = 0;
      Tile* t = tiles_.find(window.row0 + window.rowOf(v), window.col0 + window.colOf(v), &k, true);
      const float outlier = res > threshold ? 1.0f : 0.0f;
      if (t->observations[k] == 0) {
        t->residual[k] = res;
        t->outlier_rate[k] = outlier;
      } else {
        t->residual[k] += w * (res - t->residual[k]);
        t->outlier_rate[k] += w * (outlier - t->outlier_rate[k]);
      }
      if (t->observations[k] < 65535) ++t->observations[k];
      ++updated;
    }
  }
  previous_left_ = left.clone();  // its own buffer: the estimator may reuse its buffers, and copies of this object share the old one
  previous_camera_T_ground_ = camera_T_ground;
  return updated;
}

cv::Mat PhotometricResidualMap::layer(Layer which, const GroundGrid& grid) const {
  if (std::abs(grid.resolution_m - resolution_m_) > 1e-9) {
    throw std::invalid_argument("PhotometricResidualMap::layer: grid resolution differs from the map's");
  }
  cv::Mat out(grid.rows, grid.cols, CV_32F, cv::Scalar(kNaN));
  LatticeTiles<Tile>::Reader reader(tiles_);
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      size_t k = 0;
      const Tile* t = reader.find(grid.row0 + r, grid.col0 + c, &k);
      if (!t || t->observations[k] == 0) continue;
      out.at<float>(r, c) = which == Layer::kResidual      ? t->residual[k]
                            : which == Layer::kOutlierRate ? t->outlier_rate[k]
                                                           : static_cast<float>(t->observations[k]);
    }
  }
  return out;
}

cv::Mat PhotometricResidualMap::contradicted(const GroundGrid& grid) const {
  return layer(Layer::kOutlierRate, grid) >= options_.max_published_outlier_rate;  // NaN compares false
}

int PhotometricResidualMap::unpublishContradicted(const GroundGrid& grid, const std::vector<cv::Mat*>& layers) const {
  const cv::Mat mask = contradicted(grid);
  for (cv::Mat* l : layers) {
    if (l && !l->empty()) l->setTo(std::numeric_limits<float>::quiet_NaN(), mask);
  }
  return cv::countNonZero(mask);
}

void PhotometricResidualMap::clear() {
  tiles_.clear();
  previous_left_.release();
  last_median_ = std::numeric_limits<double>::quiet_NaN();
}

void PhotometricResidualMap::write(std::ostream& out) const {
  const std::int32_t size[2] = {previous_left_.rows, previous_left_.cols};
  out.write(reinterpret_cast<const char*>(size), sizeof(size));
  for (int r = 0; r < previous_left_.rows; ++r)
    out.write(reinterpret_cast<const char*>(previous_left_.ptr<float>(r)),
              static_cast<std::streamsize>(previous_left_.cols * sizeof(float)));
  const Eigen::Matrix4d pose = previous_camera_T_ground_.matrix();
  out.write(reinterpret_cast<const char*>(pose.data()), sizeof(double) * 16);
  out.write(reinterpret_cast<const char*>(&last_median_), sizeof(last_median_));
  tiles_.write(out);
}

void PhotometricResidualMap::read(std::istream& in) {
  std::int32_t size[2] = {0, 0};
  in.read(reinterpret_cast<char*>(size), sizeof(size));
  if (!in || size[0] < 0 || size[1] < 0 || static_cast<long long>(size[0]) * size[1] > (1LL << 28))
    throw std::runtime_error("residual record: bad previous image size");
  cv::Mat previous(size[0], size[1], CV_32FC1);
  for (int r = 0; r < previous.rows; ++r)
    in.read(reinterpret_cast<char*>(previous.ptr<float>(r)), static_cast<std::streamsize>(previous.cols * sizeof(float)));
  Eigen::Matrix4d pose;
  double median = 0.0;
  in.read(reinterpret_cast<char*>(pose.data()), sizeof(double) * 16);
  in.read(reinterpret_cast<char*>(&median), sizeof(median));
  if (!in || !pose.allFinite()) throw std::runtime_error("residual record: truncated or a non-finite pose");
  tiles_.read(in);  // throws before anything changes
  previous_left_ = previous;
  previous_camera_T_ground_.matrix() = pose;
  last_median_ = median;
}

}  // namespace stereo_ground_dem
