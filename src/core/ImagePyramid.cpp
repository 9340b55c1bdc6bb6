#include "stereo_ground_dem/ImagePyramid.hpp"

#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace stereo_ground_dem {

cv::Mat ImagePyramid::toGrayFloat(const cv::Mat& image, ColorOrder order) {
  GreyConverterOptions limits;
  limits.min_side_px = 1;
  return GreyConverter::toGrey(image, 16, order, GreyConverter::kHostByteOrder, limits);
}

ImagePyramid::ImagePyramid(const cv::Mat& image, int levels, ColorOrder order,
                           double presmooth_sigma_px) {
  if (levels < 1) throw std::invalid_argument("ImagePyramid needs at least one level");
  levels_.resize(static_cast<size_t>(levels));
  levels_[0].image = toGrayFloat(image, order);
  if (levels_[0].image.data == image.data) levels_[0].image = levels_[0].image.clone();
  if (presmooth_sigma_px > 0.0) {
    cv::GaussianBlur(levels_[0].image, levels_[0].image, cv::Size(0, 0), presmooth_sigma_px, presmooth_sigma_px,
                     cv::BORDER_REPLICATE);
  }
  for (int l = 1; l < levels; ++l) {
    cv::pyrDown(levels_[static_cast<size_t>(l - 1)].image, levels_[static_cast<size_t>(l)].image);
  }
  const cv::Mat kernel = (cv::Mat_<float>(1, 3) << -0.5f, 0.0f, 0.5f);
  for (auto& lv : levels_) {
    cv::filter2D(lv.image, lv.grad_u, CV_32F, kernel, cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
    cv::filter2D(lv.image, lv.grad_v, CV_32F, kernel.t(), cv::Point(-1, -1), 0.0,
                 cv::BORDER_REPLICATE);
  }
}

}  // namespace stereo_ground_dem
