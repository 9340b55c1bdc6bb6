#include "stereo_ground_dem/ros/TraversabilityCostTable.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stereo_ground_dem {

TraversabilityCostTable::TraversabilityCostTable() {
  table_[0] = kLethal;
  for (int b = 1; b < kBins; ++b) {
    const long v = std::lround(100.0 * (1.0 - static_cast<double>(b) / (kBins - 1)));
    table_[static_cast<size_t>(b)] = static_cast<int8_t>(std::min(99L, v));
  }
}

int8_t TraversabilityCostTable::occupancy(float t) const {
  if (!std::isfinite(t)) return kUnknown;
  const float clamped = std::min(1.0f, std::max(0.0f, t));
  return table_[static_cast<size_t>(std::lround(clamped * (kBins - 1)))];
}

nav_msgs::OccupancyGrid TraversabilityCostTable::toOccupancyGrid(const GroundGrid& grid, const cv::Mat& trav,
                                                                 const cv::Mat& observations, int min_observations,
                                                                 const std_msgs::Header& header,
                                                                 const cv::Mat& obstacle, const cv::Mat& probability,
                                                                 double min_certainty) const {
  const cv::Size size(grid.cols, grid.rows);
  if (trav.type() != CV_32F || trav.size() != size) {
    throw std::invalid_argument("traversability layer does not match the grid");
  }
  const bool use_obs = !observations.empty();
  if (use_obs && (observations.type() != CV_32F || observations.size() != size)) {
    throw std::invalid_argument("observations layer does not match the grid");
  }
  const bool use_obstacle = !obstacle.empty();
  if (use_obstacle && (obstacle.type() != CV_32F || obstacle.size() != size)) {
    throw std::invalid_argument("obstacle layer does not match the grid");
  }
  const bool use_certainty = !probability.empty() && min_certainty > 0.5;
  if (use_certainty && (probability.type() != CV_32F || probability.size() != size)) {
    throw std::invalid_argument("traversability probability layer does not match the grid");
  }
  nav_msgs::OccupancyGrid g;
  g.header = header;
  g.info.map_load_time = header.stamp;
  g.info.resolution = static_cast<float>(grid.resolution_m);
  g.info.width = static_cast<uint32_t>(grid.cols);
  g.info.height = static_cast<uint32_t>(grid.rows);
  g.info.origin.position.x = grid.x0() - 0.5 * grid.resolution_m;
  g.info.origin.position.y = grid.y0() - 0.5 * grid.resolution_m;
  g.info.origin.position.z = 0.0;
  g.info.origin.orientation.w = 1.0;
  g.data.resize(static_cast<size_t>(grid.rows) * static_cast<size_t>(grid.cols));
  for (int r = 0; r < grid.rows; ++r) {
    const float* t = trav.ptr<float>(r);
    const float* o = use_obs ? observations.ptr<float>(r) : nullptr;
    const float* ob = use_obstacle ? obstacle.ptr<float>(r) : nullptr;
    const float* p = use_certainty ? probability.ptr<float>(r) : nullptr;
    int8_t* out = g.data.data() + static_cast<size_t>(r) * static_cast<size_t>(grid.cols);
    for (int c = 0; c < grid.cols; ++c) {
      const bool certain = !p || std::max(p[c], 1.0f - p[c]) >= static_cast<float>(min_certainty);  // NaN: false
      const bool seen = (!use_obs || (std::isfinite(o[c]) && o[c] >= static_cast<float>(min_observations))) && certain;
      out[c] = ob && ob[c] >= 0.5f ? kLethal : seen ? occupancy(t[c]) : kUnknown;
    }
  }
  return g;
}

}  // namespace stereo_ground_dem
