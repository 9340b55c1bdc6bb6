#pragma once
/// \file TriangleRasterizer.hpp
/// Z-buffered scan conversion of projected planar triangles into a label image: each pixel centre
/// belongs to the nearest triangle covering it (largest inverse depth), so that pixels are assigned
/// to the surface actually visible. Shared edges are covered without holes (inclusive edge test;
/// the first triangle drawn wins exact ties).

#include <opencv2/core.hpp>
#include <vector>

namespace stereo_ground_dem {

class TriangleRasterizer {
 public:
  /// A triangle in pixel coordinates with its inverse depth rho(u, v) = a u + b v + c [1/m].
  struct Triangle {
    double u[3], v[3];
    double rho_a, rho_b, rho_c;
    int id;  ///< written to the label image, >= 0
  };

  /// Clears the buffers for an image of width x height; pixels closer than `margin` to the border
  /// are never covered.
  void reset(int width, int height, int margin);
  /// Draws a triangle; returns the number of pixels it won at the time of drawing. Only rows
  /// first_row..last_row are touched: threads can draw bands of rows at once.
  int draw(const Triangle& tri, int first_row = 0, int last_row = 1 << 30);

  const cv::Mat& labels() const { return labels_; }             ///< CV_32S, -1 = none
  const cv::Mat& inverseDepth() const { return inv_depth_; }    ///< CV_32F, 0 = none
  /// First and last column with a label in row v (first > last when the row is empty).
  int rowBegin(int v) const { return row_begin_[static_cast<size_t>(v)]; }
  int rowEnd(int v) const { return row_end_[static_cast<size_t>(v)]; }

 private:
  cv::Mat labels_;
  cv::Mat inv_depth_;
  std::vector<int> row_begin_, row_end_;
  int margin_ = 0;
};

}  // namespace stereo_ground_dem
