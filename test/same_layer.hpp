#pragma once
// Whether two float layers are identical, NaN where the other is NaN (maps compared bit for bit).
#include <cmath>
#include <opencv2/core.hpp>

namespace stereo_ground_dem {
namespace test {

inline bool sameLayer(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size()) return false;
  for (int r = 0; r < a.rows; ++r)
    for (int c = 0; c < a.cols; ++c) {
      const float x = a.at<float>(r, c), y = b.at<float>(r, c);
      if (std::isnan(x) != std::isnan(y) || (!std::isnan(x) && x != y)) return false;
    }
  return true;
}

}  // namespace test
}  // namespace stereo_ground_dem
