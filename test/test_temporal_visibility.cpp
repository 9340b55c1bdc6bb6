// TemporalVisibility: ground the previous camera did not see, from the surface rendered into
// both views. A ridge across the road, the camera 1 m nearer than before: the ground in the strip
// between the ridge's two occlusion shadows is seen now and was hidden then.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/TemporalVisibility.hpp"
#include "stereo_ground_dem/sim/StereoRenderer.hpp"

using namespace stereo_ground_dem;

namespace {

constexpr double kCameraHeightM = 1.65;
constexpr double kRidgeXM = 10.0, kRidgeHeightM = 0.6, kRidgeHalfWidthM = 1.0;

/// A camera kCameraHeightM above the ground at (x, 0), looking along +x (level).
Eigen::Isometry3d groundTCamera(double x) {
  Eigen::Isometry3d g_T_c = Eigen::Isometry3d::Identity();
  g_T_c.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;  // columns: camera x, y, z in the ground frame
  g_T_c.translation() = Eigen::Vector3d(x, 0.0, kCameraHeightM);
  return g_T_c;
}

struct RidgeScene {
  StereoRig rig = sim::StereoRenderer::kittiLikeRig(1.0);
  StereoEstimator stereo{rig, StereoEstimatorOptions()};
  ImagePyramid pyramid = stereo.makePyramid(cv::Mat(rig.height, rig.width, CV_8U, cv::Scalar(128)));
  GroundGrid grid = GroundGrid::covering(-4.0, 40.0, -16.0, 16.0, 0.5, 8);
  Eigen::VectorXd heights(bool ridge) const {
    Eigen::VectorXd z = Eigen::VectorXd::Zero(grid.vertexCount());
    if (!ridge) return z;
    for (int v = 0; v < grid.vertexCount(); ++v) {
      const double d = std::abs(grid.position(v).x() - kRidgeXM);
      z[v] = kRidgeHeightM * std::max(0.0, 1.0 - d / kRidgeHalfWidthM);
    }
    return z;
  }
  /// Hidden pixels at pyramid level `level` of the camera at x = 0 against the one at x = prev_x,
  /// and the ground x [m] of each.
  cv::Mat hidden(bool ridge, double prev_x, int level, const TemporalVisibilityOptions& o,
                 std::vector<double>* ground_x = nullptr) const {
    const Eigen::VectorXd z = heights(ridge);
    const Eigen::Isometry3d cur = groundTCamera(0.0), prev = groundTCamera(prev_x);
    const cv::Mat rho = stereo.surfaceInverseDepth(pyramid, grid, z, cur.inverse(), level);
    const cv::Mat rho_prev = stereo.surfaceInverseDepth(pyramid, grid, z, prev.inverse(), level);
    const StereoRig r = rig.atLevel(level);
    const cv::Mat m = TemporalVisibility(o).hidden(rho, rho_prev, r, prev.inverse() * cur);
    if (ground_x) {
      for (int v = 0; v < m.rows; ++v)
        for (int u = 0; u < m.cols; ++u) {
          if (!m.at<uint8_t>(v, u)) continue;
          const double depth = 1.0 / rho.at<float>(v, u);
          const Eigen::Vector3d xc((u - r.cx) / r.fx * depth, (v - r.cy) / r.fy * depth, depth);
          ground_x->push_back((cur * xc).x());
        }
    }
    return m;
  }
};

}  // namespace

// The ridge (0.6 m high at 10 m, flanks 1 m wide) hides the ground from its crest to
// 10 + 10 * 0.6 / 1.05 = 15.71 m from the camera at x = 0 and to 10 + 11 * 0.6 / 1.05 = 16.29 m
// from the one at x = -1: the hidden pixels are the ground in between (and the ridge's back flank
// is seen from neither). Level ground seen by a level camera has one depth per image row, and a
// row of level 1 spans 0.44 m of ground at 16 m: measured (level 1, no dilation) 609 pixels, the
// whole row at x = 16.01 m.
TEST(TemporalVisibility, GroundRevealedBehindARidgeIsHidden) {
  const RidgeScene s;
  TemporalVisibilityOptions o;
  o.dilation_px = 0;
  std::vector<double> xs;
  const cv::Mat m = s.hidden(true, -1.0, 1, o, &xs);
  const int n = cv::countNonZero(m);
  ASSERT_GT(n, 0);
  const auto [lo, hi] = std::minmax_element(xs.begin(), xs.end());
  std::printf("[ ridge    ] hidden %d px at level 1, ground x %.2f-%.2f m\n", n, *lo, *hi);
  EXPECT_GT(n, 400);   // a row
  EXPECT_LT(n, 1300);  // two
  EXPECT_GT(*lo, 15.5);
  EXPECT_LT(*hi, 16.5);
}

// Nothing is hidden on level ground, nor between a view and itself; the tolerance keeps a point on
// the visible surface (it meets itself in the other view's rendering) from being hidden.
TEST(TemporalVisibility, NothingHiddenOnLevelGroundOrFromTheSameView) {
  const RidgeScene s;
  TemporalVisibilityOptions o;
  EXPECT_EQ(cv::countNonZero(s.hidden(false, -1.0, 1, o)), 0);
  EXPECT_EQ(cv::countNonZero(s.hidden(true, 0.0, 1, o)), 0);
  EXPECT_EQ(cv::countNonZero(s.hidden(false, -1.0, 0, o)), 0);
}

// The mask on every pyramid level (ImagePyramid::maskOnEveryLevel, which the obstacle mask uses
// too): nearest-neighbour to the finer ones, any-of to the coarser.
TEST(TemporalVisibility, MaskOnEveryLevel) {
  const RidgeScene s;
  TemporalVisibilityOptions o;
  const cv::Mat m = s.hidden(true, -1.0, 1, o);
  const std::vector<cv::Mat> all = s.pyramid.maskOnEveryLevel(m, 1);
  ASSERT_EQ(static_cast<int>(all.size()), s.pyramid.levels());
  EXPECT_EQ(cv::countNonZero(all[1] != m), 0);
  EXPECT_EQ(cv::countNonZero(all[0]), 4 * cv::countNonZero(m));
  for (size_t k = 2; k < all.size(); ++k) {
    EXPECT_EQ(all[k].size(), s.pyramid.level(static_cast<int>(k)).image.size());
    EXPECT_GT(cv::countNonZero(all[k]), 0);
    EXPECT_LE(cv::countNonZero(all[k]), cv::countNonZero(all[k - 1]));
  }
  EXPECT_THROW(s.pyramid.maskOnEveryLevel(m, 2), std::invalid_argument);
  TemporalVisibilityOptions bad;
  bad.inverse_depth_tolerance = 0.0;
  EXPECT_THROW(TemporalVisibility{bad}, std::invalid_argument);
}
