#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "stereo_ground_dem/ImagePyramid.hpp"

using stereo_ground_dem::ImagePyramid;

TEST(ImagePyramid, SizesAndGradientsOfARamp) {
  cv::Mat img(370, 1226, CV_8U);
  for (int v = 0; v < img.rows; ++v)
    for (int u = 0; u < img.cols; ++u) img.at<uint8_t>(v, u) = static_cast<uint8_t>((u / 8 + v / 4) % 256);
  const ImagePyramid pyr(img, 4);
  ASSERT_EQ(pyr.levels(), 4);
  EXPECT_EQ(pyr.width(1), 613);
  EXPECT_EQ(pyr.height(3), 47);
  // a linear ramp I = 2u + 3v has gradient (2, 3) in the interior at level 0
  cv::Mat ramp(50, 60, CV_32F);
  for (int v = 0; v < ramp.rows; ++v)
    for (int u = 0; u < ramp.cols; ++u) ramp.at<float>(v, u) = 2.0f * u + 3.0f * v;
  const ImagePyramid rp(ramp, 2);
  EXPECT_FLOAT_EQ(rp.level(0).grad_u.at<float>(20, 30), 2.0f);
  EXPECT_FLOAT_EQ(rp.level(0).grad_v.at<float>(20, 30), 3.0f);
  // at level 1 the pixel spacing doubles: the gradient per (level-1) pixel doubles
  EXPECT_NEAR(rp.level(1).grad_u.at<float>(10, 15), 4.0f, 1e-3);
  EXPECT_NEAR(rp.level(1).grad_v.at<float>(10, 15), 6.0f, 1e-3);
  // pyrDown output pixel i is centred on input pixel 2i: the ramp value matches
  EXPECT_NEAR(rp.level(1).image.at<float>(10, 15), 2.0f * 30 + 3.0f * 20, 1e-3);
}

TEST(ImagePyramid, ConvertsDepthsAndColour) {
  cv::Mat g8(4, 4, CV_8U, cv::Scalar(200));
  cv::Mat g16(4, 4, CV_16U, cv::Scalar(65535));
  cv::Mat bgr(4, 4, CV_8UC3, cv::Scalar(255, 0, 0));  // pure blue in BGR order
  EXPECT_FLOAT_EQ(ImagePyramid::toGrayFloat(g8).at<float>(0, 0), 200.0f);
  EXPECT_FLOAT_EQ(ImagePyramid::toGrayFloat(g16).at<float>(0, 0), 255.0f);
  const float blue_as_bgr = ImagePyramid::toGrayFloat(bgr, ImagePyramid::ColorOrder::kBgr).at<float>(0, 0);
  const float blue_as_rgb = ImagePyramid::toGrayFloat(bgr, ImagePyramid::ColorOrder::kRgb).at<float>(0, 0);
  EXPECT_NEAR(blue_as_bgr, 0.114f * 255, 1.0f);  // blue weight
  EXPECT_NEAR(blue_as_rgb, 0.299f * 255, 1.0f);  // read as red
  EXPECT_THROW(ImagePyramid::toGrayFloat(cv::Mat(4, 4, CV_64F)), std::invalid_argument);
  EXPECT_THROW(ImagePyramid::toGrayFloat(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(ImagePyramid::toGrayFloat(cv::Mat(4, 4, CV_8UC2)), std::invalid_argument);
}

TEST(ImagePyramid, RowRangeStatisticsAreOpenCvsAndRemembered) {
  // rows v hold the value v (mean of rows [10, 20) = 14.5, standard deviation sqrt(8.25))
  cv::Mat img(40, 30, CV_8U);
  for (int v = 0; v < img.rows; ++v) img.row(v).setTo(v);
  const ImagePyramid pyr(img, 2);
  double mean = 0.0, sd = 0.0;
  pyr.rowRangeStats(10, 20, &mean, &sd);
  EXPECT_NEAR(mean, 14.5, 1e-12);
  EXPECT_NEAR(sd, std::sqrt(8.25), 1e-12);
  const double first_mean = mean, first_sd = sd;
  cv::Scalar m, s;
  cv::meanStdDev(pyr.level(0).image.rowRange(3, 37), m, s);
  pyr.rowRangeStats(3, 37, &mean, &sd);
  EXPECT_EQ(mean, m[0]);
  EXPECT_EQ(sd, s[0]);
  // asked again, by a copy too: the same numbers (the copy shares the images and what was computed)
  const ImagePyramid copy = pyr;
  double mean2 = 0.0, sd2 = 0.0;
  copy.rowRangeStats(10, 20, &mean2, &sd2);
  EXPECT_EQ(mean2, first_mean);
  EXPECT_EQ(sd2, first_sd);
  // more ranges than it remembers: the oldest is computed again, with the same result
  for (int v0 = 0; v0 < 30; ++v0) pyr.rowRangeStats(v0, v0 + 5, &mean, &sd);
  pyr.rowRangeStats(10, 20, &mean, &sd);
  EXPECT_EQ(mean, first_mean);
  EXPECT_EQ(sd, first_sd);
  pyr.rowRangeStats(25, 30, &mean, &sd);
  EXPECT_NEAR(mean, 27.0, 1e-12);
  EXPECT_THROW(pyr.rowRangeStats(-1, 5, &mean, &sd), std::out_of_range);
  EXPECT_THROW(pyr.rowRangeStats(30, 41, &mean, &sd), std::out_of_range);
  EXPECT_THROW(pyr.rowRangeStats(5, 5, &mean, &sd), std::out_of_range);
  EXPECT_THROW(ImagePyramid().rowRangeStats(0, 1, &mean, &sd), std::out_of_range);
}
