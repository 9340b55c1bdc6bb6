#include "stereo_ground_dem/OrthoTexture.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "stereo_ground_dem/ImagePyramid.hpp"
#include <string>

namespace stereo_ground_dem {

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

}  // namespace

bool OrthoTextureOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(resolution_m >= 0.01 && resolution_m <= 10.0)) return bad("resolution_m must be in 0.01..10");
  if (tile_size < 8 || tile_size > 4096) return bad("tile_size must be in 8..4096");
  if (!(keep_radius_m > 0.0)) return bad("keep_radius_m must be > 0");
  if (!(min_range_m > 0.0 && max_range_m > min_range_m)) return bad("need 0 < min_range_m < max_range_m");
  if (!(min_pixels_per_texel >= 0.0 && std::isfinite(min_pixels_per_texel))) return bad("min_pixels_per_texel must be >= 0");
  if (!(better_view_ratio > 1.0 && std::isfinite(better_view_ratio))) return bad("better_view_ratio must be > 1");
  if (max_average_views < 1 || max_average_views > 255) return bad("max_average_views must be in 1..255");
  if (image_margin_px < 1 || image_margin_px > 1000) return bad("image_margin_px must be in 1..1000");
  return true;
}

OrthoTexture::OrthoTexture(const OrthoTextureOptions& options)
    : options_(options), tiles_(options.tile_size, options.resolution_m) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("OrthoTextureOptions: " + why);
}

OrthoTexture::Tile::Tile(size_t n) : value(n, kNaN), quality(n, 0.0f), views(n, 0) {}

int OrthoTexture::update(const ElevationMap& map, const GroundGrid& window, const cv::Mat& left, const StereoRig& rig,
                         const Eigen::Isometry3d& ground_T_camera, const PhotometricParams& left_vs_previous) {
  if (!options_.enabled) return 0;
  if (left.type() != CV_32FC1) throw std::invalid_argument("OrthoTexture::update: the left image must be CV_32F grey");
  if (left.cols < 2 || left.rows < 2) throw std::invalid_argument("OrthoTexture::update: empty left image");
  // Exposure chain: L_k = g L_{k-1} + b, so L_{k-1} = (L_k - b) / g and the reference map of L_k
  // is the previous one applied to that. An implausible step is not chained (identity).
  const double g = left_vs_previous.gain, b = left_vs_previous.bias_grey;
  if (!has_reference_) {
    to_reference_ = PhotometricParams();
    has_reference_ = true;
  } else if (std::isfinite(g) && std::isfinite(b) && g > 0.2 && g < 5.0 && std::abs(b) < 255.0) {
    to_reference_ = {to_reference_.gain / g, to_reference_.bias_grey - to_reference_.gain * b / g};
  }
  if (window.vertexCount() == 0) return 0;

  Eigen::VectorXd z, info;
  map.sample(window, &z, &info);
  const cv::Mat obstacle = map.layer(ElevationMap::Layer::kObstacle, window);
  const Eigen::Isometry3d camera_T_ground = ground_T_camera.inverse();
  const Eigen::Matrix3d R = camera_T_ground.linear();
  const Eigen::Vector3d t = camera_T_ground.translation();
  const double res = options_.resolution_m, R_m = window.resolution_m;
  const double u_min = options_.image_margin_px, v_min = options_.image_margin_px;
  const double u_max = left.cols - 1 - options_.image_margin_px, v_max = left.rows - 1 - options_.image_margin_px;
  const double gain_ref = to_reference_.gain, bias_ref = to_reference_.bias_grey;
  const double texel_area = res * res;
  const double min_q = options_.min_pixels_per_texel, ratio = options_.better_view_ratio;
  const int max_views = options_.max_average_views;
  auto blocked = [&](int r, int c) { return obstacle.at<float>(r, c) == 1.0f; };
  int written = 0;
  for (int r = 0; r + 1 < window.rows; ++r) {
    for (int c = 0; c + 1 < window.cols; ++c) {
      const double z00 = z[window.index(r, c)], z01 = z[window.index(r, c + 1)];
      const double z10 = z[window.index(r + 1, c)], z11 = z[window.index(r + 1, c + 1)];
      if (!(std::isfinite(z00) && std::isfinite(z01) && std::isfinite(z10) && std::isfinite(z11))) continue;
      if (blocked(r, c) || blocked(r, c + 1) || blocked(r + 1, c) || blocked(r + 1, c + 1)) continue;
      const double xc = window.xOfCol(c), yc = window.yOfRow(r);
      // Quick reject: the square's centre far outside the range band (the square is < 1 m).
      const Eigen::Vector3d centre = R * Eigen::Vector3d(xc + 0.5 * R_m, yc + 0.5 * R_m, 0.25 * (z00 + z01 + z10 + z11)) + t;
      if (centre.z() < options_.min_range_m - 2.0 * R_m || centre.z() > options_.max_range_m + 2.0 * R_m) continue;
      // Both triangles' normals N = (-dz/dx, -dz/dy, 1) in the camera frame (GroundGrid's split along
      // (r,c)-(r+1,c+1)); not normalized: |N| is the surface area over a unit of ground area.
      const Eigen::Vector3d na = R * Eigen::Vector3d(-(z01 - z00) / R_m, -(z11 - z01) / R_m, 1.0);  // s >= t
      const Eigen::Vector3d nb = R * Eigen::Vector3d(-(z11 - z10) / R_m, -(z10 - z00) / R_m, 1.0);  // t > s
      const long long j_lo = static_cast<long long>(std::ceil(xc / res - 1e-6));
      const long long j_hi = static_cast<long long>(std::ceil((xc + R_m) / res - 1e-6)) - 1;
      const long long i_lo = static_cast<long long>(std::ceil(yc / res - 1e-6));
      const long long i_hi = static_cast<long long>(std::ceil((yc + R_m) / res - 1e-6)) - 1;
      for (long long i = i_lo; i <= i_hi; ++i) {
        const double y = i * res, tt = std::clamp((y - yc) / R_m, 0.0, 1.0);
        for (long long j = j_lo; j <= j_hi; ++j) {
          const double x = j * res, s = std::clamp((x - xc) / R_m, 0.0, 1.0);
          const bool upper = tt > s;
          const double h = upper ? z00 + tt * (z10 - z00) + s * (z11 - z10) : z00 + s * (z01 - z00) + tt * (z11 - z01);
          const Eigen::Vector3d pc = R * Eigen::Vector3d(x, y, h) + t;
          if (pc.z() < options_.min_range_m || pc.z() > options_.max_range_m) continue;
          const double iz = 1.0 / pc.z();
          const double u = rig.fx * pc.x() * iz + rig.cx, v = rig.fy * pc.y() * iz + rig.cy;
          if (!(u >= u_min && u <= u_max && v >= v_min && v <= v_max)) continue;
          // The surface faces the camera only when N . X < 0 (X: from the camera to the point); a
          // back-facing triangle shows whatever hides it. (Terrain hidden by nearer terrain in front
          // is not tested: obstacle cells are the only occluders left out.)
          const double facing = -(upper ? nb : na).dot(pc);
          if (!(facing > 0.0)) continue;
          // Image pixels per texel side: sqrt(f^2 |N . X| / Z^3 * texel area).
          const double q = std::sqrt(rig.fx * rig.fy * facing * iz * iz * iz * texel_area);
          if (q < min_q) continue;
          const float value = std::clamp(static_cast<float>(gain_ref * ImagePyramid::sampleBilinear(left, u, v) + bias_ref), 0.0f, 255.0f);
          if (!std::isfinite(value)) continue;
          size_t k = 0;
          Tile* tile = tiles_.find(i, j, &k, true);
          const float stored_q = tile->quality[k];
          if (tile->views[k] == 0 || q >= ratio * stored_q) {
            tile->value[k] = value;
            tile->quality[k] = static_cast<float>(q);
            tile->views[k] = 1;
          } else if (q * ratio >= stored_q) {
            const int n = std::min<int>(tile->views[k] + 1, max_views);
            tile->value[k] += (value - tile->value[k]) / static_cast<float>(n);
            tile->quality[k] = std::max(stored_q, static_cast<float>(q));
            tile->views[k] = static_cast<uint8_t>(n);
          } else {
            continue;
          }
          ++written;
        }
      }
    }
  }
  return written;
}

cv::Mat OrthoTexture::sample(const GroundGrid& grid) const {
  cv::Mat out(grid.rows, grid.cols, CV_32F, cv::Scalar(kNaN));
  const double res = options_.resolution_m;
  // Texels within half a cell of the vertex: a box of h texels on each side (h = 0 at the texel
  // resolution: the texel itself), read at most kBoxSamples x kBoxSamples (a stride through larger
  // boxes: a whole-map window of 2 m cells would otherwise read every texel).
  constexpr int kBoxSamples = 5;
  const int h = std::abs(grid.resolution_m - res) < 1e-9 ? 0 : std::max(0, static_cast<int>(0.5 * grid.resolution_m / res + 1e-6));
  const int stride = std::max(1, (2 * h + kBoxSamples) / kBoxSamples);
  LatticeTiles<Tile>::Reader reader(tiles_);
  for (int r = 0; r < grid.rows; ++r) {
    const long long ic = std::llround(grid.yOfRow(r) / res);
    for (int c = 0; c < grid.cols; ++c) {
      const long long jc = std::llround(grid.xOfCol(c) / res);
      double sum = 0.0;
      int n = 0;
      for (long long i = ic - h; i <= ic + h; i += stride) {
        for (long long j = jc - h; j <= jc + h; j += stride) {
          size_t k = 0;
          const Tile* tile = reader.find(i, j, &k);
          if (!tile || tile->views[k] == 0) continue;
          sum += tile->value[k];
          ++n;
        }
      }
      if (n > 0) out.at<float>(r, c) = static_cast<float>(sum / n);
    }
  }
  return out;
}

bool OrthoTexture::knownExtent(long long* i0_out, long long* i1_out, long long* j0_out, long long* j1_out) const {
  long long i0 = std::numeric_limits<long long>::max(), j0 = i0, i1 = std::numeric_limits<long long>::min(), j1 = i1;
  const long long ts = options_.tile_size;
  tiles_.forEach([&](long long row0, long long col0, const Tile& tile) {
    for (long long a = 0; a < ts; ++a) {
      for (long long b = 0; b < ts; ++b) {
        if (tile.views[static_cast<size_t>(a * ts + b)] == 0) continue;
        i0 = std::min(i0, row0 + a);
        i1 = std::max(i1, row0 + a);
        j0 = std::min(j0, col0 + b);
        j1 = std::max(j1, col0 + b);
      }
    }
  });
  if (i1 < i0) return false;
  *i0_out = i0;
  *i1_out = i1;
  *j0_out = j0;
  *j1_out = j1;
  return true;
}

GroundGrid OrthoTexture::knownBounds(int factor) const {
  GroundGrid g;
  g.resolution_m = factor * options_.resolution_m;
  long long i0 = 0, i1 = 0, j0 = 0, j1 = 0;
  if (factor < 1 || !knownExtent(&i0, &i1, &j0, &j1)) return g;
  auto floorDiv = [](long long a, long long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); };
  const long long r0 = floorDiv(i0, factor), r1 = floorDiv(i1, factor), c0 = floorDiv(j0, factor), c1 = floorDiv(j1, factor);
  const long long rows = r1 - r0 + 1, cols = c1 - c0 + 1;
  if (rows * cols > GroundGrid::kMaxVertices || std::max(std::llabs(r0), std::llabs(r1)) > GroundGrid::kMaxLatticeIndex ||
      std::max(std::llabs(c0), std::llabs(c1)) > GroundGrid::kMaxLatticeIndex) {
    throw std::length_error("OrthoTexture: the known texture spans " + std::to_string(rows) + " x " +
                            std::to_string(cols) + " texels of " + std::to_string(g.resolution_m) +
                            " m, beyond GroundGrid's limits");
  }
  g.row0 = static_cast<int>(r0);
  g.col0 = static_cast<int>(c0);
  g.rows = static_cast<int>(rows);
  g.cols = static_cast<int>(cols);
  return g;
}

cv::Mat OrthoTexture::raster(GroundGrid* grid, long long max_texels) const {
  long long i0 = 0, i1 = 0, j0 = 0, j1 = 0;
  GroundGrid g;
  g.resolution_m = options_.resolution_m;
  if (knownExtent(&i0, &i1, &j0, &j1)) {
    // The smallest integer coarsening that keeps the raster within max_texels.
    long long f = 1;
    while (((i1 - i0) / f + 2) * ((j1 - j0) / f + 2) > std::max(1LL, max_texels)) ++f;
    g = knownBounds(static_cast<int>(f));
  }
  if (grid) *grid = g;
  if (g.vertexCount() == 0) return cv::Mat();
  return sample(g);
}

int OrthoTexture::evictFarFrom(double x, double y) { return tiles_.evictFarFrom(x, y, options_.keep_radius_m); }

void OrthoTexture::clear() {
  tiles_.clear();
  to_reference_ = PhotometricParams();
  has_reference_ = false;
}

size_t OrthoTexture::memoryBytes() const {
  const size_t per = static_cast<size_t>(options_.tile_size) * static_cast<size_t>(options_.tile_size) *
                     (sizeof(float) * 2 + sizeof(uint8_t));
  return tiles_.size() * per;
}

void OrthoTexture::write(std::ostream& out) const {
  const double reference[2] = {to_reference_.gain, to_reference_.bias_grey};
  const std::int32_t has = has_reference_ ? 1 : 0;
  out.write(reinterpret_cast<const char*>(reference), sizeof(reference));
  out.write(reinterpret_cast<const char*>(&has), sizeof(has));
  tiles_.write(out);
}

void OrthoTexture::read(std::istream& in) {
  double reference[2] = {1.0, 0.0};
  std::int32_t has = 0;
  in.read(reinterpret_cast<char*>(reference), sizeof(reference));
  in.read(reinterpret_cast<char*>(&has), sizeof(has));
  if (!in || !std::isfinite(reference[0]) || !std::isfinite(reference[1]) || reference[0] <= 0.0)
    throw std::runtime_error("ortho-texture record: bad exposure reference");
  tiles_.read(in);  // throws before anything changes
  to_reference_ = {reference[0], reference[1]};
  has_reference_ = has != 0;
}

}  // namespace stereo_ground_dem
