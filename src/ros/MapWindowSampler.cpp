#include "stereo_ground_dem/ros/MapWindowSampler.hpp"

#include <algorithm>
#include <cmath>

namespace stereo_ground_dem {

const cv::Mat* DemLayers::find(const std::string& name) const {
  for (const GridLayer& l : layers)
    if (l.name == name) return &l.values;
  return nullptr;
}

int DemLayers::knownCount() const {
  const cv::Mat* e = find("elevation");
  if (!e) return 0;
  int n = 0;
  for (int r = 0; r < e->rows; ++r)
    for (int c = 0; c < e->cols; ++c) n += std::isfinite(e->at<float>(r, c));
  return n;
}

MapWindowSampler::MapWindowSampler(const TraversabilityOptions& options) : filter_(options) {}

void MapWindowSampler::setTraversability(const TraversabilityOptions& options) {
  filter_ = TraversabilityFilter(options);
}

GroundGrid MapWindowSampler::window(double res, double cx, double cy, double size_x_m, double size_y_m) {
  GroundGrid g;
  g.resolution_m = res;
  g.cols = std::max(2, static_cast<int>(std::ceil(size_x_m / res - 1e-9)) + 1);
  g.rows = std::max(2, static_cast<int>(std::ceil(size_y_m / res - 1e-9)) + 1);
  g.col0 = static_cast<int>(std::lround(cx / res - 0.5 * (g.cols - 1)));
  g.row0 = static_cast<int>(std::lround(cy / res - 0.5 * (g.rows - 1)));
  return g;
}

int MapWindowSampler::stride(int rows, int cols, int max_cells) {
  if (max_cells <= 0) return 1;
  int s = 1;
  while (static_cast<long>((rows + s - 1) / s) * ((cols + s - 1) / s) > max_cells) ++s;
  return s;
}

DemLayers MapWindowSampler::sample(const ElevationMap& map, const GroundGrid& requested, int max_cells,
                                   const ExtraLayerSources& extra) const {
  // The window aligned to the stride so that the decimated grid is on a lattice too; aligning can
  // add a row and a column of the coarser lattice, so the stride grows until those fit as well
  // (up to the window's size, where the coarse grid has 2 or 3 vertices a side).
  auto aligned = [&requested](int k) {
    auto floorTo = [k](int v) { return static_cast<int>(std::floor(static_cast<double>(v) / k)) * k; };
    const int c1 = requested.col0 + requested.cols - 1, r1 = requested.row0 + requested.rows - 1;
    GroundGrid a = requested;
    a.col0 = floorTo(requested.col0);
    a.row0 = floorTo(requested.row0);
    a.cols = floorTo(c1 - a.col0 + k - 1) + 1;
    a.rows = floorTo(r1 - a.row0 + k - 1) + 1;
    return a;
  };
  auto coarseCount = [](const GroundGrid& a, int k) {
    return static_cast<long>((a.rows - 1) / k + 1) * ((a.cols - 1) / k + 1);
  };
  GroundGrid w = requested;
  int s = stride(w.rows, w.cols, max_cells);
  if (s > 1) {
    w = aligned(s);
    const int s_max = std::max(requested.rows, requested.cols);
    while (coarseCount(w, s) > max_cells && s < s_max) w = aligned(++s);
  }
  // the filter on a padded window, cropped back
  const TraversabilityWindows fw = filter_.windows(w.resolution_m);
  const int pad = std::max({fw.slope_half, fw.step_half, fw.roughness_half, 1});
  GroundGrid padded = w;
  padded.row0 -= pad;
  padded.col0 -= pad;
  padded.rows += 2 * pad;
  padded.cols += 2 * pad;
  cv::Mat elevation_padded = map.layer(ElevationMap::Layer::kElevation, padded);
  cv::Mat variance = map.layer(ElevationMap::Layer::kVariance, padded);
  // heights the images kept contradicting (PhotometricResidualMap::contradicted) are unknown
  if (extra.residual) extra.residual->unpublishContradicted(padded, {&elevation_padded, &variance});
  const TraversabilityLayers t = filter_.compute(padded, elevation_padded);
  const cv::Rect inner(pad, pad, w.cols, w.rows);

  // Obstacles (ElevationMap::Layer::kObstacle: 1 obstacle, 0 ground seen last, NaN unknown) are
  // not traversable whatever the ground around them looks like: traversability 0 (lethal), also
  // where the ground under the obstacle is unknown (hidden).
  const cv::Mat obstacle = map.layer(ElevationMap::Layer::kObstacle, w);
  cv::Mat traversability = t.traversability(inner).clone();
  traversability.setTo(0.0f, obstacle >= 0.5f);  // NaN compares false: unknown stays as it is
  // The probability of being traversable from the heights' variance (0 on obstacles too).
  cv::Mat probability = filter_.probability(padded, t, variance)(inner).clone();
  probability.setTo(0.0f, obstacle >= 0.5f);

  DemLayers out;
  out.grid = w;
  out.layers = {{"elevation", elevation_padded(inner).clone()},
                {"variance", variance(inner).clone()},
                {"observations", map.layer(ElevationMap::Layer::kObservations, w)},
                {"slope", t.slope_rad(inner).clone()},
                {"step", t.step_m(inner).clone()},
                {"roughness", t.roughness_m(inner).clone()},
                {"traversability", traversability},
                {"traversability_confidence", probability},
                {"obstacle", obstacle},
                {"obstacle_height", map.layer(ElevationMap::Layer::kObstacleHeight, w)}};
  if (extra.residual) {
    out.layers.push_back({"residual", extra.residual->layer(PhotometricResidualMap::Layer::kResidual, w)});
    out.layers.push_back(
        {"residual_outlier_rate", extra.residual->layer(PhotometricResidualMap::Layer::kOutlierRate, w)});
  }
  if (s > 1) {
    out.grid = w.coarsened(s);
    for (GridLayer& l : out.layers) {
      cv::Mat d(out.grid.rows, out.grid.cols, CV_32F);
      for (int r = 0; r < d.rows; ++r)
        for (int c = 0; c < d.cols; ++c) d.at<float>(r, c) = l.values.at<float>(r * s, c * s);
      l.values = d;
    }
  }
  // The intensity at the published cells directly (each the mean over its own, coarser cell).
  if (extra.ortho) out.layers.push_back({"intensity", extra.ortho->sample(out.grid)});
  return out;
}

}  // namespace stereo_ground_dem
