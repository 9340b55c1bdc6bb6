#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <stdexcept>

#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/SkylineMask.hpp"

using stereo_ground_dem::ImagePyramid;
using stereo_ground_dem::SkylineMask;
using stereo_ground_dem::SkylineMaskOptions;

namespace {

/// 400 x 300: rows above `horizon` a blank sky (grey 200, noise sigma 1 grey, as the renderer's
/// sky), below it textured ground (uniform noise 40..160).
cv::Mat skyAndGround(int horizon) {
  cv::Mat img(300, 400, CV_8U);
  cv::RNG rng(7);
  cv::Mat sky(horizon, 400, CV_32F), ground(300 - horizon, 400, CV_8U);
  rng.fill(sky, cv::RNG::NORMAL, 200.0, 1.0);
  sky.convertTo(img.rowRange(0, horizon), CV_8U);
  rng.fill(ground, cv::RNG::UNIFORM, 40, 160);
  ground.copyTo(img.rowRange(horizon, 300));
  return img;
}

int markedInRows(const cv::Mat& m, int r0, int r1) { return cv::countNonZero(m.rowRange(r0, r1)); }

}  // namespace

// The band lies along the outline: from rows_above above the first row the 9 px box sees as
// textured to rows_below below it, in every column, and nowhere else.
TEST(SkylineMask, BandAlongTheOutlineOfGroundAgainstSky) {
  const int horizon = 120;
  const ImagePyramid p(skyAndGround(horizon), 3);
  const std::vector<cv::Mat> m = SkylineMask(SkylineMaskOptions()).compute(p);
  ASSERT_EQ(m.size(), 3u);
  for (int l = 0; l < 3; ++l) {
    EXPECT_EQ(m[static_cast<size_t>(l)].size(), p.level(l).image.size()) << l;
    EXPECT_EQ(m[static_cast<size_t>(l)].type(), CV_8U) << l;
  }
  // the band: 2 + 8 + 12 = 22 rows in every column from just above the horizon (the box mean
  // turns textured ~5 rows above it), nothing elsewhere
  const cv::Mat& m0 = m[0];
  EXPECT_EQ(markedInRows(m0, horizon - 10, horizon + 20), 22 * 400);
  EXPECT_EQ(cv::countNonZero(m0), 22 * 400);
  // level 1: 2 + 8 + 12 / 2 = 16 rows in its own pixels around horizon / 2
  const cv::Mat& m1 = m[1];
  EXPECT_GT(markedInRows(m1, horizon / 2 - 10, horizon / 2 + 14), 0.95 * 16 * m1.cols);
  EXPECT_LE(cv::countNonZero(m1), 16 * m1.cols);
  EXPECT_EQ(cv::countNonZero(m1), markedInRows(m1, horizon / 2 - 10, horizon / 2 + 14));
  // from level 1 on only (the estimator's finest temporal level): level 0 left empty, the rest the same
  const std::vector<cv::Mat> from1 = SkylineMask(SkylineMaskOptions()).compute(p, 1);
  ASSERT_EQ(from1.size(), 3u);
  EXPECT_TRUE(from1[0].empty());
  EXPECT_EQ(cv::countNonZero(from1[1] != m1), 0);
}

// Ground alone, a blank slab inside it (smooth asphalt) or a sky shorter than min_blank_rows
// marks nothing; disabled, no masks at all.
TEST(SkylineMask, NothingWithoutATallBlankRun) {
  cv::Mat img = skyAndGround(1);
  const std::vector<cv::Mat> none = SkylineMask(SkylineMaskOptions()).compute(ImagePyramid(img, 2));
  ASSERT_EQ(none.size(), 2u);
  EXPECT_EQ(cv::countNonZero(none[0]), 0);
  // a blank slab 100 rows tall inside the ground: not a background (it does not reach the top)
  img(cv::Rect(100, 150, 200, 100)).setTo(120);
  EXPECT_EQ(cv::countNonZero(SkylineMask(SkylineMaskOptions()).compute(ImagePyramid(img, 2))[0]), 0);
  // sky 15 rows tall only: shorter than min_blank_rows (20), nothing
  EXPECT_EQ(cv::countNonZero(SkylineMask(SkylineMaskOptions()).compute(ImagePyramid(skyAndGround(15), 1))[0]), 0);
  SkylineMaskOptions off;
  off.enabled = false;
  EXPECT_TRUE(SkylineMask(off).compute(ImagePyramid(img, 2)).empty());
}

TEST(SkylineMask, RejectsInvalidOptions) {
  SkylineMaskOptions o;
  o.window_px = 8;
  EXPECT_THROW(SkylineMask{o}, std::invalid_argument);
  o = SkylineMaskOptions();
  o.blank_gradient_grey_per_px = 0.0;
  EXPECT_THROW(SkylineMask{o}, std::invalid_argument);
  o = SkylineMaskOptions();
  o.rows_below = -1;
  EXPECT_THROW(SkylineMask{o}, std::invalid_argument);
  o = SkylineMaskOptions();
  o.reveal_rows = -1;
  EXPECT_THROW(SkylineMask{o}, std::invalid_argument);
}
