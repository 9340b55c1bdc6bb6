#include "stereo_ground_dem/SkylineMask.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

bool SkylineMaskOptions::isValid(std::string* why) const {
  auto bad = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(blank_gradient_grey_per_px > 0.0)) return bad("blank_gradient_grey_per_px must be > 0");
  if (window_px < 1 || window_px % 2 == 0) return bad("window_px must be odd and >= 1");
  if (min_blank_rows < 1) return bad("min_blank_rows must be >= 1");
  if (rows_above < 0 || rows_below < 0 || reveal_rows < 0) return bad("rows_above, rows_below and reveal_rows must be >= 0");
  return true;
}

SkylineMask::SkylineMask(const SkylineMaskOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("SkylineMaskOptions: " + why);
}

cv::Mat SkylineMask::level(const cv::Mat& grad_u, const cv::Mat& grad_v, int l) const {
  CV_Assert(grad_u.type() == CV_32F && grad_v.type() == CV_32F && grad_u.size() == grad_v.size());
  cv::Mat magnitude, mean;
  cv::magnitude(grad_u, grad_v, magnitude);
  cv::blur(magnitude, mean, cv::Size(options_.window_px, options_.window_px), cv::Point(-1, -1), cv::BORDER_REPLICATE);
  const float blank = static_cast<float>(options_.blank_gradient_grey_per_px);
  const int min_run = std::max(3, options_.min_blank_rows >> l);
  const int below = options_.rows_below + (options_.reveal_rows >> l);
  const int rows = mean.rows, cols = mean.cols;
  cv::Mat mask = cv::Mat::zeros(mean.size(), CV_8U);
  // Per column: the blank run from the image's top edge down to the first textured row. Only
  // that outline: a blank patch within the ground (smooth asphalt) is not a background.
  std::vector<int> run(static_cast<size_t>(cols), 0);  // blank rows from the top, -1 once textured
  int open = cols;  // columns still blank from the top
  for (int v = 0; v < rows && open > 0; ++v) {
    const float* m = mean.ptr<float>(v);
    for (int u = 0; u < cols; ++u) {
      int& r = run[static_cast<size_t>(u)];
      if (r < 0) continue;
      if (m[u] < blank) {
        ++r;
        continue;
      }
      if (r >= min_run) {
        const int v0 = std::max(0, v - options_.rows_above), v1 = std::min(rows, v + below);
        for (int w = v0; w < v1; ++w) mask.at<uint8_t>(w, u) = 255;
      }
      r = -1;
      --open;
    }
  }
  return mask;
}

std::vector<cv::Mat> SkylineMask::compute(const ImagePyramid& pyramid, int first_level) const {
  std::vector<cv::Mat> masks;
  if (!options_.enabled || pyramid.empty()) return masks;
  masks.resize(static_cast<size_t>(pyramid.levels()));
  // Each level from its own gradients: the pyramid's blur widens the outline's edge by about a
  // pixel of that level, so the band holds it in that level's pixels.
  for (int l = std::max(0, first_level); l < pyramid.levels(); ++l)
    masks[static_cast<size_t>(l)] = level(pyramid.level(l).grad_u, pyramid.level(l).grad_v, l);
  return masks;
}

}  // namespace stereo_ground_dem
