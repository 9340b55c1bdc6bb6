#include "stereo_ground_dem/ros/HeightMeshBuilder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace stereo_ground_dem {

namespace {
int triangles(int rows, int cols) { return rows > 1 && cols > 1 ? 2 * (rows - 1) * (cols - 1) : 0; }
int decimatedCount(int n, int s) { return (n - 1) / s + 1; }
}  // namespace

int HeightMeshBuilder::stride(int rows, int cols, int max_triangles) {
  int s = 1;
  while (triangles(decimatedCount(rows, s), decimatedCount(cols, s)) > std::max(2, max_triangles)) ++s;
  return s;
}

std_msgs::ColorRGBA HeightMeshBuilder::color(double u, float alpha) {
  // Stops of a viridis-like map: dark blue, blue, green, yellow-green, yellow.
  static const std::array<std::array<float, 3>, 5> kStops = {{{0.27f, 0.00f, 0.33f},
                                                              {0.23f, 0.32f, 0.55f},
                                                              {0.13f, 0.57f, 0.55f},
                                                              {0.37f, 0.79f, 0.38f},
                                                              {0.99f, 0.91f, 0.14f}}};
  if (!std::isfinite(u)) u = 0.0;
  u = std::min(1.0, std::max(0.0, u));
  const double x = u * (kStops.size() - 1);
  const size_t i = std::min(kStops.size() - 2, static_cast<size_t>(x));
  const float f = static_cast<float>(x - static_cast<double>(i));
  std_msgs::ColorRGBA c;
  c.r = kStops[i][0] + f * (kStops[i + 1][0] - kStops[i][0]);
  c.g = kStops[i][1] + f * (kStops[i + 1][1] - kStops[i][1]);
  c.b = kStops[i][2] + f * (kStops[i + 1][2] - kStops[i][2]);
  c.a = alpha;
  return c;
}

visualization_msgs::Marker HeightMeshBuilder::build(const GroundGrid& grid, const cv::Mat& elevation,
                                                    const std_msgs::Header& header,
                                                    const HeightMeshOptions& options, const cv::Mat* intensity,
                                                    const cv::Mat* residual) {
  if (elevation.type() != CV_32F || elevation.rows != grid.rows || elevation.cols != grid.cols) {
    throw std::invalid_argument("elevation layer does not match the grid");
  }
  const bool grey = options.colors == MeshColors::kIntensity && intensity && !intensity->empty();
  if (grey && (intensity->type() != CV_32F || intensity->size() != elevation.size())) {
    throw std::invalid_argument("intensity layer does not match the grid");
  }
  const bool misfit = options.colors == MeshColors::kResidual && residual && !residual->empty();
  if (misfit && (residual->type() != CV_32F || residual->size() != elevation.size())) {
    throw std::invalid_argument("residual layer does not match the grid");
  }
  visualization_msgs::Marker m;
  m.header = header;
  m.ns = options.ns;
  m.id = options.id;
  m.type = visualization_msgs::Marker::TRIANGLE_LIST;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.color.r = m.color.g = m.color.b = 1.0f;
  m.color.a = options.alpha;
  m.frame_locked = false;

  // colour range
  double lo = options.color_min_m, hi = options.color_max_m;
  if (!std::isfinite(lo) || !std::isfinite(hi)) {
    std::vector<float> known;
    known.reserve(static_cast<size_t>(grid.vertexCount()));
    for (int r = 0; r < grid.rows; ++r) {
      const float* z = elevation.ptr<float>(r);
      for (int c = 0; c < grid.cols; ++c)
        if (std::isfinite(z[c])) known.push_back(z[c]);
    }
    if (!known.empty()) {
      auto at = [&known](double q) {
        const size_t k = std::min(known.size() - 1, static_cast<size_t>(q * static_cast<double>(known.size() - 1)));
        std::nth_element(known.begin(), known.begin() + static_cast<std::ptrdiff_t>(k), known.end());
        return static_cast<double>(known[k]);
      };
      if (!std::isfinite(lo)) lo = at(0.02);
      if (!std::isfinite(hi)) hi = at(0.98);
    }
  }
  if (!std::isfinite(lo) || !std::isfinite(hi)) lo = 0.0, hi = 1.0;
  if (hi - lo < 1e-3) hi = lo + 1e-3;

  const int s = stride(grid.rows, grid.cols, options.max_triangles);
  const int rows = decimatedCount(grid.rows, s), cols = decimatedCount(grid.cols, s);
  auto z = [&](int r, int c) { return elevation.at<float>(r * s, c * s); };
  auto push = [&](int r, int c) {
    geometry_msgs::Point p;
    p.x = grid.xOfCol(c * s);
    p.y = grid.yOfRow(r * s);
    p.z = z(r, c);
    m.points.push_back(p);
    const float g = grey ? intensity->at<float>(r * s, c * s) : std::numeric_limits<float>::quiet_NaN();
    if (misfit) {
      const float e = residual->at<float>(r * s, c * s);
      std_msgs::ColorRGBA k;
      k.a = options.alpha;
      if (std::isfinite(e)) {
        const float u = std::min(1.0f, std::max(0.0f, static_cast<float>(e / options.residual_max_grey)));
        k.r = std::min(1.0f, 2.0f * u);           // green -> yellow -> red
        k.g = std::min(1.0f, 2.0f * (1.0f - u));
        k.b = 0.0f;
      } else {
        k.r = k.g = k.b = 0.5f;
      }
      m.colors.push_back(k);
    } else if (std::isfinite(g)) {
      std_msgs::ColorRGBA k;
      k.r = k.g = k.b = std::min(1.0f, std::max(0.0f, g / 255.0f));
      k.a = options.alpha;
      m.colors.push_back(k);
    } else {
      m.colors.push_back(color((p.z - lo) / (hi - lo), options.alpha));
    }
  };
  m.points.reserve(static_cast<size_t>(3 * triangles(rows, cols)));
  m.colors.reserve(m.points.capacity());
  for (int r = 0; r + 1 < rows; ++r) {
    for (int c = 0; c + 1 < cols; ++c) {
      // GroundGrid's split along the (r, c)-(r+1, c+1) diagonal, counter-clockwise seen from above.
      const bool a = std::isfinite(z(r, c)), b = std::isfinite(z(r, c + 1)), d = std::isfinite(z(r + 1, c + 1)),
                 e = std::isfinite(z(r + 1, c));
      if (a && b && d) push(r, c), push(r, c + 1), push(r + 1, c + 1);
      if (a && d && e) push(r, c), push(r + 1, c + 1), push(r + 1, c);
    }
  }
  if (m.points.empty()) m.action = visualization_msgs::Marker::DELETE;
  return m;
}

}  // namespace stereo_ground_dem
