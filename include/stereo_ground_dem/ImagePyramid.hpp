#pragma once
/// \file ImagePyramid.hpp
/// Grey-level image pyramid with gradients, the only image representation the estimators use.
/// Intensities are float in 8-bit grey levels (0..255) whatever the input depth, so that every
/// photometric parameter (robust scale, bias) has one unit.

#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/GreyConverter.hpp"

namespace stereo_ground_dem {

class ImagePyramid {
 public:
  using ColorOrder = GreyConverter::ColorOrder;

  struct Level {
    cv::Mat image;  ///< CV_32F, grey levels
    cv::Mat grad_u; ///< CV_32F, d image / d u (central differences) [grey/px]
    cv::Mat grad_v; ///< CV_32F, d image / d v [grey/px]
  };

  ImagePyramid() = default;
  /// Builds `levels` levels (level 0 = input resolution) with cv::pyrDown.
  /// Accepts what GreyConverter accepts (CV_8UC1/3/4, CV_16UC1/3/4 taken as full 16-bit range,
  /// CV_32FC1 already in grey levels), up to its size limits (no minimum here); throws
  /// std::invalid_argument otherwise. 12-bit data in 16-bit samples must go through a
  /// GreyConverter first (its CV_32F output is taken as it is).
  /// `presmooth_sigma_px` > 0 blurs level 0 with a Gaussian first: bilinear sampling of the other
  /// image at sub-pixel positions attenuates fine texture, which biases the gain estimate upward
  /// (measured: +0.75 % unsmoothed, +0.25 % with 0.8 px on rendered pairs); a little smoothing of
  /// both images removes most of it at no cost in height accuracy.
  ImagePyramid(const cv::Mat& image, int levels, ColorOrder order = ColorOrder::kBgr,
               double presmooth_sigma_px = 0.0);

  /// Converts any accepted input to single-channel CV_32F grey levels (0..255):
  /// GreyConverter::toGrey with 16 significant bits and no minimum size.
  static cv::Mat toGrayFloat(const cv::Mat& image, ColorOrder order = ColorOrder::kBgr);
  /// Bilinear sample of a CV_32F image at (u, v); the caller keeps 0 <= u < cols - 1, 0 <= v < rows - 1.
  static float sampleBilinear(const cv::Mat& image, double u, double v) {
    const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
    const float a = static_cast<float>(u - u0), b = static_cast<float>(v - v0);
    const float* r0 = image.ptr<float>(v0) + u0;
    const float* r1 = image.ptr<float>(v0 + 1) + u0;
    return (1.0f - b) * ((1.0f - a) * r0[0] + a * r0[1]) + b * ((1.0f - a) * r1[0] + a * r1[1]);
  }

  int levels() const { return static_cast<int>(levels_.size()); }
  const Level& level(int l) const { return levels_.at(static_cast<size_t>(l)); }
  int width(int l = 0) const { return level(l).image.cols; }
  int height(int l = 0) const { return level(l).image.rows; }
  bool empty() const { return levels_.empty(); }
  /// A CV_8U mask of level `level` (of its size) on every level: nearest-neighbour to the finer
  /// levels, any-of 2 x 2 to the coarser ones (a pixel of a coarser level is set when any pixel it
  /// covers is). Throws std::invalid_argument when the mask does not match the level.
  std::vector<cv::Mat> maskOnEveryLevel(const cv::Mat& mask, int level) const;
  /// Mean and standard deviation of rows [v0, v1) of level 0's image (cv::meanStdDev), remembered
  /// per pyramid (and its copies, which share the images): the pose search asks for the same rows
  /// of the same images several times a frame. Thread-safe. Throws std::out_of_range for rows
  /// outside the image or an empty range.
  void rowRangeStats(int v0, int v1, double* mean, double* stddev) const;

 private:
  std::vector<Level> levels_;
  struct RowStats {
    int v0, v1;
    double mean, stddev;
  };
  struct StatsCache {
    std::mutex mutex;
    std::vector<RowStats> entries;  ///< the most recent last
  };
  std::shared_ptr<StatsCache> stats_ = std::make_shared<StatsCache>();
};

}  // namespace stereo_ground_dem
