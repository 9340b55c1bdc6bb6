#pragma once
/// \file HeightGridConverter.hpp
/// DEM layers <-> stereo_ground_dem/HeightGrid (field for field grid_map_msgs/GridMap).
///
/// Two conventions meet here (both written down in msg/HeightGrid.msg and docs/ros.md):
///  - the DEM (GroundGrid.hpp): vertex (r, c) at x = x0 + c * res, y = y0 + r * res, row-major
///    cv::Mat, rows along +y, columns along +x;
///  - grid_map (grid_map_core/src/GridMapMath.cpp): cell index (i, j) with (0, 0) at the largest
///    x and y, i along -x, j along -y, the layer an Eigen column-major matrix of size
///    (cells along x) x (cells along y), Float32MultiArray labels "column_index" / "row_index".
/// Each grid_map cell is centred on one DEM vertex: cell (i, j) = vertex (rows-1-j, cols-1-i), the
/// grid's centre is the centre of the vertex rectangle and its lengths are cells * resolution.

#include <std_msgs/Header.h>

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/HeightGrid.h"
#include "stereo_ground_dem/ros/GridLayer.hpp"

namespace stereo_ground_dem {

class HeightGridConverter {
 public:
  /// Builds the message; every layer must be CV_32F of grid.rows x grid.cols (throws
  /// std::invalid_argument otherwise). basic_layers = {"elevation"} when such a layer exists.
  static HeightGrid toMessage(const GroundGrid& grid, const std::vector<GridLayer>& layers,
                              const std_msgs::Header& header);

  /// The inverse: the DEM grid (on the lattice of the message's resolution) and the layers.
  /// Accepts column- and row-major layouts and non-zero start indices as grid_map does; returns
  /// false with the reason for an inconsistent message.
  static bool fromMessage(const HeightGrid& message, GroundGrid* grid, std::vector<GridLayer>* layers,
                          std::string* why);
};

}  // namespace stereo_ground_dem
