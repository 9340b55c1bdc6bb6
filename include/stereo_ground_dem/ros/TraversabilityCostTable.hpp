#pragma once
/// \file TraversabilityCostTable.hpp
/// Traversability (0 = not traversable .. 1 = flat, NaN unknown; TraversabilityFilter.hpp) to
/// nav_msgs/OccupancyGrid values through a lookup table, as costmap_2d translates its costs:
///   traversability t is quantized to bin b = round(255 * t) and
///   occupancy(b) = 100 (lethal) for b = 0 (t = 0: some ratio reached its critical value),
///                  min(99, round(100 * (1 - b / 255))) otherwise (0 = free for t = 1),
///   -1 (unknown) for NaN, and for vertices observed by fewer than `min_observations` frames;
///   100 (lethal) wherever the obstacle layer is 1, whatever the rest (the ground under an
///   obstacle is often unknown: hidden).
/// The grid's cells are centred on the DEM vertices: cell (col c, row r) = vertex (r, c), the origin
/// (lower-left corner of cell (0, 0)) half a cell below and left of vertex (0, 0), data row-major
/// with rows along +y as OccupancyGrid wants; the orientation is the identity.

#include <nav_msgs/OccupancyGrid.h>
#include <std_msgs/Header.h>

#include <array>
#include <cstdint>
#include <opencv2/core.hpp>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

class TraversabilityCostTable {
 public:
  static constexpr int kBins = 256;
  static constexpr int8_t kUnknown = -1;
  static constexpr int8_t kLethal = 100;
  static constexpr int8_t kFree = 0;

  TraversabilityCostTable();

  /// The occupancy of one traversability value (NaN -> -1; values are clamped to 0..1).
  int8_t occupancy(float traversability) const;
  const std::array<int8_t, kBins>& table() const { return table_; }

  /// `traversability`, `observations` and `obstacle` (1 obstacle, 0 / NaN not): CV_32F grid.rows x
  /// grid.cols (observations and obstacle may be empty to skip them). With `probability` (P of
  /// being traversable, same size) and min_certainty > 0.5, cells whose decision is less certain,
  /// max(P, 1 - P) < min_certainty, are unknown (-1); obstacles stay lethal. Throws
  /// std::invalid_argument on a size or type mismatch.
  nav_msgs::OccupancyGrid toOccupancyGrid(const GroundGrid& grid, const cv::Mat& traversability,
                                          const cv::Mat& observations, int min_observations,
                                          const std_msgs::Header& header,
                                          const cv::Mat& obstacle = cv::Mat(), const cv::Mat& probability = cv::Mat(),
                                          double min_certainty = 0.0) const;

 private:
  std::array<int8_t, kBins> table_{};
};

}  // namespace stereo_ground_dem
