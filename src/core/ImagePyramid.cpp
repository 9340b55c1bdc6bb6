#include "stereo_ground_dem/ImagePyramid.hpp"

#include <algorithm>
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

std::vector<cv::Mat> ImagePyramid::maskOnEveryLevel(const cv::Mat& mask, int level) const {
  const int n = levels();
  if (level < 0 || level >= n || mask.type() != CV_8U || mask.size() != this->level(level).image.size()) {
    throw std::invalid_argument("ImagePyramid::maskOnEveryLevel: the mask is not CV_8U of the level's size");
  }
  std::vector<cv::Mat> out(static_cast<size_t>(n));
  out[static_cast<size_t>(level)] = mask.clone();
  for (int k = level - 1; k >= 0; --k) {
    cv::resize(out[static_cast<size_t>(k + 1)], out[static_cast<size_t>(k)], this->level(k).image.size(), 0, 0,
               cv::INTER_NEAREST);
  }
  for (int k = level + 1; k < n; ++k) {
    const cv::Mat& fine = out[static_cast<size_t>(k - 1)];
    cv::Mat coarse = cv::Mat::zeros(this->level(k).image.size(), CV_8U);
    for (int v = 0; v < coarse.rows; ++v) {
      uint8_t* c = coarse.ptr<uint8_t>(v);
      for (int u = 0; u < coarse.cols; ++u) {
        uint8_t any = 0;
        for (int dv = 0; dv < 2; ++dv)
          for (int du = 0; du < 2; ++du)
            any |= fine.at<uint8_t>(std::min(2 * v + dv, fine.rows - 1), std::min(2 * u + du, fine.cols - 1));
        c[u] = any;
      }
    }
    out[static_cast<size_t>(k)] = coarse;
  }
  return out;
}

}  // namespace stereo_ground_dem

namespace stereo_ground_dem {

void ImagePyramid::rowRangeStats(int v0, int v1, double* mean, double* stddev) const {
  const cv::Mat& img = level(0).image;
  if (v0 < 0 || v1 > img.rows || v0 >= v1) throw std::out_of_range("ImagePyramid::rowRangeStats: rows outside the image");
  constexpr size_t kEntries = 16;
  std::lock_guard<std::mutex> lock(stats_->mutex);
  std::vector<RowStats>& e = stats_->entries;
  for (const RowStats& r : e) {
    if (r.v0 == v0 && r.v1 == v1) {
      *mean = r.mean;
      *stddev = r.stddev;
      return;
    }
  }
  cv::Scalar m, s;
  cv::meanStdDev(img.rowRange(v0, v1), m, s);
  if (e.size() >= kEntries) e.erase(e.begin());
  e.push_back({v0, v1, m[0], s[0]});
  *mean = m[0];
  *stddev = s[0];
}

}  // namespace stereo_ground_dem
