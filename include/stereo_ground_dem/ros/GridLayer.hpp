#pragma once
/// \file GridLayer.hpp
/// One named layer of a DEM window.

#include <opencv2/core.hpp>
#include <string>

namespace stereo_ground_dem {

/// CV_32F, grid.rows x grid.cols, element (r, c) = vertex (r, c) of its GroundGrid, NaN unknown.
struct GridLayer {
  std::string name;
  cv::Mat values;
};

}  // namespace stereo_ground_dem
