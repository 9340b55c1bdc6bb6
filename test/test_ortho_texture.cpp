// OrthoTexture: the image draped on the map, exact on a plane seen by a pinhole camera; the
// exposure chain, the best-resolved view, obstacle cells, the per-cell sample and the picture's
// orientation.
#include <gtest/gtest.h>

#include <cmath>

#include "stereo_ground_dem/OrthoTexture.hpp"
#include "stereo_ground_dem/PhotometricResidualMap.hpp"
#include "level_ground_views.hpp"

#include <opencv2/imgproc.hpp>

namespace sgd = stereo_ground_dem;

namespace {

sgd::StereoRig rig() { return sgd::test::levelGroundRig(); }
Eigen::Isometry3d camera(double x) { return sgd::test::levelGroundCamera(x); }
double albedo(double x, double y) { return sgd::test::levelGroundAlbedo(x, y); }
cv::Mat image(const Eigen::Isometry3d& g_t_c, double gain = 1.0, double bias = 0.0, double offset = 0.0) {
  return sgd::test::levelGroundImage(g_t_c, gain, bias, offset);
}
sgd::ElevationMap levelMap(sgd::GroundGrid* window) { return sgd::test::levelGroundMap(window); }

/// Largest |texture - expected| over the known texels with x in [x0, x1], y in [y0, y1]; counts them.
double worstError(const sgd::OrthoTexture& t, double x0, double x1, double offset, int* known, double y0 = -3.0,
                  double y1 = 3.0) {
  const sgd::GroundGrid g = sgd::GroundGrid::covering(x0, x1, y0, y1, 0.1);
  const cv::Mat m = t.sample(g);
  double worst = 0.0;
  *known = 0;
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) {
      const float v = m.at<float>(r, c);
      if (!std::isfinite(v)) continue;
      ++*known;
      worst = std::max(worst, std::abs(v - (albedo(g.xOfCol(c), g.yOfRow(r)) + offset)));
    }
  }
  return worst;
}

}  // namespace

TEST(OrthoTexture, DrapesTheImageOnALevelGroundExactly) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTexture t;
  const int written = t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  int known = 0;
  // 6.2 m: the bottom image row; 30 m: max_range_m.
  const double worst = worstError(t, 7.0, 29.0, 0.0, &known);
  // The error is the image's bilinear interpolation, growing with the ground a pixel spans.
  // Measured worst per band: 7-12 m 0.098, 10-15 0.18, 15-20 0.45, 20-25 0.79, 25-30 2.0 grey.
  const double bands[][3] = {{7.0, 12.0, 0.2}, {10.0, 15.0, 0.36}, {15.0, 20.0, 0.9}, {20.0, 25.0, 1.6}};
  for (const auto& b : bands) {
    int k = 0;
    const double e = worstError(t, b[0], b[1], 0.0, &k);
    std::printf("[ ortho ] %.0f-%.0f m: worst %.3f grey\n", b[0], b[1], e);
    EXPECT_LT(e, b[2]) << b[0];
  }
  std::printf("[ ortho ] %d texels written, %d in the 7-29 m road strip, worst |error| %.3f grey\n", written, known, worst);
  EXPECT_EQ(known, 221 * 61);
  EXPECT_LT(worst, 3.0);
  int none = 0;
  worstError(t, 31.0, 40.0, 0.0, &none);  // beyond max_range_m
  EXPECT_EQ(none, 0);
  worstError(t, 0.0, 5.8, 0.0, &none);  // below the image
  EXPECT_EQ(none, 0);
  EXPECT_GT(t.tileCount(), 0u);
  EXPECT_EQ(t.memoryBytes(), t.tileCount() * 256u * 256u * 9u);
}

TEST(OrthoTexture, ChainsTheExposureToTheFirstFrame) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTexture t;
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  // Frame 2: the same view, exposure x1.5 + 10 (L_2 = 1.5 L_1 + 10); frame 3: x0.8 - 4 on top.
  t.update(map, w, image(camera(0.0), 1.5, 10.0), rig(), camera(0.0), {1.5, 10.0});
  EXPECT_NEAR(t.toReference().gain, 1.0 / 1.5, 1e-12);
  EXPECT_NEAR(t.toReference().bias_grey, -10.0 / 1.5, 1e-12);
  t.update(map, w, image(camera(0.0), 1.2, 4.0), rig(), camera(0.0), {0.8, -4.0});  // 0.8 * (1.5 L + 10) - 4
  int known = 0;
  EXPECT_LT(worstError(t, 7.0, 15.0, 0.0, &known), 0.4);
  // Without the chain, the same images would move the texture by tens of grey levels.
  sgd::OrthoTexture unchained;
  unchained.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  unchained.update(map, w, image(camera(0.0), 1.5, 10.0), rig(), camera(0.0), sgd::PhotometricParams());
  EXPECT_GT(worstError(unchained, 7.0, 29.0, 0.0, &known), 30.0);
  // An implausible step is not chained.
  t.update(map, w, image(camera(0.0), 1.2, 4.0), rig(), camera(0.0), {std::nan(""), 0.0});
  EXPECT_NEAR(t.toReference().gain, 1.0 / 1.2, 1e-12);
}

TEST(OrthoTexture, KeepsTheBestResolvedView) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTexture t;
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  // 5 m further the ground 11-35 m is seen closer; this image says +20 grey (a different scene).
  t.update(map, w, image(camera(5.0), 1.0, 0.0, 20.0), rig(), camera(5.0), sgd::PhotometricParams());
  int known = 0;
  EXPECT_LT(worstError(t, 7.0, 10.0, 0.0, &known), 0.4) << "not seen from x = 5: the first view stays";
  EXPECT_GT(known, 1000);
  EXPECT_LT(worstError(t, 13.0, 20.0, 20.0, &known), 0.4) << "seen 5 m closer: replaced";
  // Back at x = 0 (a worse view of everything): nothing changes.
  t.update(map, w, image(camera(0.0), 1.0, 0.0, -50.0), rig(), camera(0.0), sgd::PhotometricParams());
  EXPECT_LT(worstError(t, 13.0, 20.0, 20.0, &known), 0.4);
  // The same view again is averaged: (20 + 30) / 2.
  t.update(map, w, image(camera(5.0), 1.0, 0.0, 30.0), rig(), camera(5.0), sgd::PhotometricParams());
  EXPECT_LT(worstError(t, 13.0, 20.0, 25.0, &known), 0.4);
}

TEST(OrthoTexture, LeavesObstacleCellsAndUnknownHeightsOut) {
  sgd::GroundGrid w;
  sgd::ElevationMap map = levelMap(&w);
  // An obstacle mark at the vertex (10, 0) and a hole in the map at (15, 1).
  std::vector<uint8_t> hit(static_cast<size_t>(w.vertexCount()), 0), ground(hit.size(), 0);
  const int obstacle_v = w.index(static_cast<int>(std::lround((0.0 - w.y0()) / 0.5)), static_cast<int>(std::lround(10.0 / 0.5)));
  hit[static_cast<size_t>(obstacle_v)] = 1;
  map.updateObstacles(w, hit, ground, Eigen::VectorXd::Constant(w.vertexCount(), std::nan("")), 0);  // two frames' evidence
  map.updateObstacles(w, hit, ground, Eigen::VectorXd::Constant(w.vertexCount(), std::nan("")), 1);
  sgd::OrthoTexture t;
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  int known = 0;
  worstError(t, 9.6, 10.4, 0.0, &known, -0.4, 0.4);  // the four squares around the marked vertex
  EXPECT_EQ(known, 0);
  EXPECT_LT(worstError(t, 8.0, 9.4, 0.0, &known, -0.4, 0.4), 0.4);
  EXPECT_GT(known, 0);
  // A map with one unknown vertex (15, 1): the four squares around it are not textured.
  sgd::ElevationMap holed;
  std::vector<uint8_t> update(static_cast<size_t>(w.vertexCount()), 1);
  update[static_cast<size_t>(w.index(static_cast<int>(std::lround((1.0 - w.y0()) / 0.5)), 30))] = 0;
  const int n = w.vertexCount();
  holed.fuse(w, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Constant(n, 1e4), update, 0);
  sgd::OrthoTexture h;
  h.update(holed, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  const sgd::GroundGrid hole = sgd::GroundGrid::covering(14.6, 15.4, 0.6, 1.4, 0.1);
  const cv::Mat m = h.sample(hole);
  EXPECT_EQ(cv::countNonZero(m == m), 0);  // all NaN
  EXPECT_LT(worstError(h, 10.0, 14.0, 0.0, &known), 0.4);
}

TEST(OrthoTexture, SamplesCellsAsTheMeanOfTheirTexels) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTexture t;
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  const sgd::GroundGrid cells = sgd::GroundGrid::covering(10.0, 12.0, -1.0, 1.0, 0.5);
  const sgd::GroundGrid texels = sgd::GroundGrid::covering(9.8, 12.2, -1.2, 1.2, 0.1);
  const cv::Mat c = t.sample(cells), x = t.sample(texels);
  for (int r = 0; r < cells.rows; ++r) {
    for (int k = 0; k < cells.cols; ++k) {
      double sum = 0.0;
      const int tr = static_cast<int>(std::lround((cells.yOfRow(r) - texels.y0()) / 0.1));
      const int tc = static_cast<int>(std::lround((cells.xOfCol(k) - texels.x0()) / 0.1));
      for (int a = -2; a <= 2; ++a)
        for (int b = -2; b <= 2; ++b) sum += x.at<float>(tr + a, tc + b);
      EXPECT_NEAR(c.at<float>(r, k), sum / 25.0, 1e-3);
    }
  }
  // The whole texture: its bounds are those of the known texels (the first and last rows and
  // columns hold some).
  sgd::GroundGrid g;
  const cv::Mat all = t.raster(&g);
  EXPECT_DOUBLE_EQ(g.resolution_m, 0.1);
  EXPECT_EQ(all.rows, g.rows);
  EXPECT_EQ(all.cols, g.cols);
  // Every texel seen (about 6.2-30 m ahead, inside the image) and nothing else: the first and last
  // rows and columns hold known texels.
  EXPECT_GT(cv::countNonZero(all.row(0) == all.row(0)), 0);
  EXPECT_GT(cv::countNonZero(all.row(all.rows - 1) == all.row(all.rows - 1)), 0);
  EXPECT_GT(cv::countNonZero(all.col(0) == all.col(0)), 0);
  EXPECT_GT(cv::countNonZero(all.col(all.cols - 1) == all.col(all.cols - 1)), 0);
  EXPECT_NEAR(g.x0(), 6.2, 0.15);
  EXPECT_NEAR(g.x0() + (g.cols - 1) * 0.1, 30.0, 0.15);
  t.clear();
  EXPECT_EQ(t.tileCount(), 0u);
  EXPECT_EQ(t.knownBounds().vertexCount(), 0);
}

TEST(OrthoTexture, CopiesShareTilesUntilWritten) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTexture t;
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  const sgd::OrthoTexture copy = t;  // what a reader on another thread holds
  t.update(map, w, image(camera(5.0), 1.0, 0.0, 20.0), rig(), camera(5.0), sgd::PhotometricParams());
  int known = 0;
  EXPECT_LT(worstError(copy, 13.0, 15.0, 0.0, &known), 0.4) << "the copy keeps the first frame's texture";
  EXPECT_LT(worstError(t, 13.0, 20.0, 20.0, &known), 0.4);
  EXPECT_EQ(copy.tileCount(), t.tileCount());
}

TEST(OrthoTexture, LeavesBackFacingGroundOut) {
  // Level to x = 10 m, then a drop of 2 m per metre: its face looks away from the camera.
  const sgd::GroundGrid w = sgd::GroundGrid::covering(0.0, 60.0, -20.0, 20.0, 0.5);
  Eigen::VectorXd z(w.vertexCount());
  for (int v = 0; v < w.vertexCount(); ++v) z[v] = std::min(0.0, -2.0 * (w.position(v).x() - 10.0));
  sgd::ElevationMap map;
  const int n = w.vertexCount();
  map.fuse(w, z, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Constant(n, 1e4), std::vector<uint8_t>(static_cast<size_t>(n), 1), 0);
  sgd::OrthoTexture t;
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  int known = 0;
  worstError(t, 10.1, 14.0, 0.0, &known);
  EXPECT_EQ(known, 0);
  EXPECT_LT(worstError(t, 7.0, 9.9, 0.0, &known), 0.4);
  EXPECT_GT(known, 1000);
}

TEST(OrthoTexture, CoarsensALargeRaster) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTexture t;
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  sgd::GroundGrid full, coarse;
  const cv::Mat a = t.raster(&full), b = t.raster(&coarse, 20000);
  EXPECT_DOUBLE_EQ(full.resolution_m, 0.1);
  EXPECT_GT(static_cast<long long>(a.rows) * a.cols, 20000);
  EXPECT_LE(static_cast<long long>(b.rows) * b.cols, 20000);
  EXPECT_GT(static_cast<long long>(b.rows) * b.cols, 5000);
  const double f = coarse.resolution_m / 0.1;
  EXPECT_NEAR(f, std::round(f), 1e-9);
  EXPECT_GE(f, 2.0);
  EXPECT_EQ(cv::countNonZero(b == b) > 0, true);
}

TEST(OrthoTexture, EvictsFarTiles) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTextureOptions o;
  o.keep_radius_m = 50.0;
  sgd::OrthoTexture t(o);
  t.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams());
  const size_t tiles = t.tileCount();
  EXPECT_EQ(t.evictFarFrom(0.0, 0.0), 0);
  EXPECT_EQ(t.evictFarFrom(200.0, 0.0), static_cast<int>(tiles));
  EXPECT_EQ(t.tileCount(), 0u);
}

TEST(OrthoTexture, RefusesBadOptionsAndImages) {
  sgd::OrthoTextureOptions o;
  std::string why;
  EXPECT_TRUE(o.isValid(&why));
  o.resolution_m = 0.0;
  EXPECT_FALSE(o.isValid(&why));
  EXPECT_EQ(why, "resolution_m must be in 0.01..10");
  o = sgd::OrthoTextureOptions();
  o.max_range_m = 0.5;
  EXPECT_FALSE(o.isValid(&why));
  o = sgd::OrthoTextureOptions();
  o.better_view_ratio = 1.0;
  EXPECT_FALSE(o.isValid(&why));
  EXPECT_THROW(sgd::OrthoTexture{o}, std::invalid_argument);
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::OrthoTexture t;
  cv::Mat u8(370, 1200, CV_8U, cv::Scalar(100));
  EXPECT_THROW(t.update(map, w, u8, rig(), camera(0.0), sgd::PhotometricParams()), std::invalid_argument);
  sgd::OrthoTextureOptions off;
  off.enabled = false;
  sgd::OrthoTexture disabled(off);
  EXPECT_EQ(disabled.update(map, w, image(camera(0.0)), rig(), camera(0.0), sgd::PhotometricParams()), 0);
  EXPECT_EQ(disabled.tileCount(), 0u);
}

// PhotometricResidualMap on the same exact views: the residual of a plane seen by a stereo pair
// whose right image has its own gain and bias is the interpolation error only; a patch painted
// into the next left image (something the ground does not explain) is flagged in its cells only.
TEST(PhotometricResidualMap, ExactOnAPlaneAndFlagsWhatTheGroundDoesNotExplain) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  sgd::PhotometricResidualMap res(0.5);
  Eigen::Isometry3d right_pose = camera(0.0);
  right_pose.translate(Eigen::Vector3d(0.54, 0.0, 0.0));
  // L = 1.25 R + 5: the right image is (scene - 5) / 1.25.
  const cv::Mat left = image(camera(0.0)), right = image(right_pose, 1.0 / 1.25, -5.0 / 1.25);
  res.update(map, w, left, right, rig(), camera(0.0), sgd::VerticalMisalignment(), {1.25, 5.0}, nullptr);
  const sgd::GroundGrid near = sgd::GroundGrid::covering(8.0, 15.0, -3.0, 3.0, 0.5);
  cv::Mat r = res.layer(sgd::PhotometricResidualMap::Layer::kResidual, near);
  double worst = 0.0;
  cv::minMaxLoc(r, nullptr, &worst, nullptr, nullptr, r == r);
  EXPECT_EQ(cv::countNonZero(r == r), near.vertexCount());
  EXPECT_LT(worst, 0.06);  // measured 0.026 grey (bilinear interpolation)
  std::printf("[ residual ] worst cell on the plane %.3f grey, frame median %.3f\n", worst, res.lastMedianResidual());
  // The next frame, 1 m on: the left image has a bright square painted where the ground at
  // x 11-12 m, y -0.5..0.5 m is seen (an object the ground does not explain).
  Eigen::Isometry3d right1 = camera(1.0);
  right1.translate(Eigen::Vector3d(0.54, 0.0, 0.0));
  cv::Mat left1 = image(camera(1.0));
  const sgd::StereoRig k = rig();
  auto pixel = [&](double x, double y) {
    const Eigen::Vector3d p = camera(1.0).inverse() * Eigen::Vector3d(x, y, 0.0);
    return cv::Point(static_cast<int>(k.fx * p.x() / p.z() + k.cx), static_cast<int>(k.fy * p.y() / p.z() + k.cy));
  };
  cv::rectangle(left1, cv::Rect(pixel(12.0, 0.5), pixel(11.0, -0.5)), cv::Scalar(250.0), cv::FILLED);
  const sgd::PhotometricParams same;
  res.update(map, w, left1, image(right1, 1.0 / 1.25, -5.0 / 1.25), rig(), camera(1.0), sgd::VerticalMisalignment(),
             {1.25, 5.0}, &same);
  const cv::Mat rate = res.layer(sgd::PhotometricResidualMap::Layer::kOutlierRate, near);
  r = res.layer(sgd::PhotometricResidualMap::Layer::kResidual, near);
  const cv::Mat obs = res.layer(sgd::PhotometricResidualMap::Layer::kObservations, near);
  int flagged_inside = 0, flagged_outside = 0;
  for (int v = 0; v < near.vertexCount(); ++v) {
    const Eigen::Vector2d p = near.position(v);
    const bool inside = p.x() > 11.2 && p.x() < 11.8 && std::abs(p.y()) < 0.3;
    // cells (vertex +- 0.25 m) that do not overlap the square x 11-12, y -0.5..0.5
    const bool outside = p.x() < 10.6 || p.x() > 12.4 || std::abs(p.y()) > 0.9;
    const float f = rate.at<float>(near.rowOf(v), near.colOf(v));
    EXPECT_EQ(obs.at<float>(near.rowOf(v), near.colOf(v)), 2.0f);
    if (inside) flagged_inside += f == 0.5f;  // one outlier frame of two, update_weight 0.5
    if (outside) flagged_outside += f != 0.0f;
  }
  EXPECT_EQ(flagged_inside, 1);  // the cell (11.5, 0), wholly inside the square
  EXPECT_EQ(flagged_outside, 0);
  // Options and inputs.
  sgd::PhotometricResidualOptions o;
  std::string why;
  EXPECT_TRUE(o.isValid(&why));
  o.update_weight = 0.0;
  EXPECT_FALSE(o.isValid(&why));
  EXPECT_EQ(why, "update_weight must be in (0, 1]");
  EXPECT_THROW(sgd::PhotometricResidualMap(0.5, o), std::invalid_argument);
  EXPECT_THROW(res.update(map, sgd::GroundGrid::covering(0, 10, 0, 10, 0.25), left, right, rig(), camera(0.0),
                          sgd::VerticalMisalignment(), {}, nullptr),
               std::invalid_argument);
  EXPECT_THROW(res.update(map, w, left, right(cv::Rect(0, 0, 100, 100)), rig(), camera(0.0), sgd::VerticalMisalignment(),
                          {}, nullptr),
               std::invalid_argument);
}

// The temporal pair's gain/bias and the stereo pair's rectification model are used as the estimator
// uses them: with them the residual is the interpolation error, without them it is not.
TEST(PhotometricResidualMap, UsesTheTemporalGainAndTheRowShift) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  Eigen::Isometry3d r0 = camera(0.0), r1 = camera(1.0);
  r0.translate(Eigen::Vector3d(0.54, 0.0, 0.0));
  r1.translate(Eigen::Vector3d(0.54, 0.0, 0.0));
  const sgd::GroundGrid near = sgd::GroundGrid::covering(9.0, 15.0, -3.0, 3.0, 0.5);
  auto median = [&](const sgd::PhotometricResidualMap& m) {
    cv::Mat r = m.layer(sgd::PhotometricResidualMap::Layer::kResidual, near);
    std::vector<float> v(r.begin<float>(), r.end<float>());
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  // Frame 1 exposed 1.2 x + 3 brighter than frame 0 (L_1 = 1.2 L_0 + 3); both pairs with L = R.
  for (const bool right_gain : {true, false}) {
    sgd::PhotometricResidualOptions o;
    o.update_weight = 1.0;  // the last frame only
    sgd::PhotometricResidualMap m(0.5, o);
    m.update(map, w, image(camera(0.0)), image(r0), rig(), camera(0.0), sgd::VerticalMisalignment(), {}, nullptr);
    const sgd::PhotometricParams temporal = right_gain ? sgd::PhotometricParams{1.2, 3.0} : sgd::PhotometricParams{};
    m.update(map, w, image(camera(1.0), 1.2, 3.0), image(r1, 1.2, 3.0), rig(), camera(1.0), sgd::VerticalMisalignment(),
             {}, &temporal);
    std::printf("[ residual ] temporal gain %s: median %.3f grey\n", right_gain ? "given" : "identity", median(m));
    if (right_gain) EXPECT_LT(median(m), 0.06);
    else EXPECT_GT(median(m), 5.0);
  }
  // The right image's rows 1.5 px low (v_right = v + 1.5): modelled, or not.
  cv::Mat shifted;
  const cv::Mat right = image(r0);
  const cv::Mat down = (cv::Mat_<double>(2, 3) << 1, 0, 0, 0, 1, 1.5);
  cv::warpAffine(right, shifted, down, right.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  sgd::VerticalMisalignment m15;
  m15.row_shift_px[0] = 1.5;
  for (const bool modelled : {true, false}) {
    sgd::PhotometricResidualMap m(0.5);
    m.update(map, w, image(camera(0.0)), shifted, rig(), camera(0.0), modelled ? m15 : sgd::VerticalMisalignment(), {},
             nullptr);
    std::printf("[ residual ] row shift %s: median %.3f grey\n", modelled ? "modelled" : "ignored", median(m));
    if (modelled) EXPECT_LT(median(m), 0.1);
    else EXPECT_GT(median(m), 1.0);
  }
}

// What the estimator explained otherwise is not held against the surface: points seen through an
// obstacle pixel are not used (the ground is hidden this frame), texture that moved (a shadow, a
// vehicle) leaves the stereo term only. contradicted() names the cells the images keep refuting,
// unpublishContradicted() takes their heights out of published layers.
TEST(PhotometricResidualMap, MaskedPixelsDoNotCountAndContradictedCellsAreNamed) {
  sgd::GroundGrid w;
  const sgd::ElevationMap map = levelMap(&w);
  const sgd::StereoRig k = rig();
  Eigen::Isometry3d right0 = camera(0.0), right1 = camera(1.0);
  right0.translate(Eigen::Vector3d(0.54, 0.0, 0.0));
  right1.translate(Eigen::Vector3d(0.54, 0.0, 0.0));
  auto pixel = [&](const Eigen::Isometry3d& pose, double x, double y) {
    const Eigen::Vector3d p = pose.inverse() * Eigen::Vector3d(x, y, 0.0);
    return cv::Point(static_cast<int>(k.fx * p.x() / p.z() + k.cx), static_cast<int>(k.fy * p.y() / p.z() + k.cy));
  };
  // frame 1 paints the ground at x 11-12 m, y -0.5..0.5 m bright in its left image (and, for texture
  // that lies on the ground, in its right image too: only the temporal pair sees a change)
  const cv::Rect square_left(pixel(camera(1.0), 12.0, 0.5), pixel(camera(1.0), 11.0, -0.5));
  struct Cell {
    float rate, observations;
    int contradicted;  ///< 1: the cell (11.5, 0) is contradicted
  };
  auto run = [&](bool on_the_ground, int obstacle_level, bool moving) {
    sgd::PhotometricResidualMap res(0.5);
    res.update(map, w, image(camera(0.0)), image(right0), k, camera(0.0), sgd::VerticalMisalignment(), {}, nullptr);
    cv::Mat left1 = image(camera(1.0)), right = image(right1);
    cv::rectangle(left1, square_left, cv::Scalar(250.0), cv::FILLED);
    if (on_the_ground) {
      cv::rectangle(right, cv::Rect(pixel(right1, 12.0, 0.5), pixel(right1, 11.0, -0.5)), cv::Scalar(250.0), cv::FILLED);
    }
    cv::Mat obstacles, moving_mask;
    if (obstacle_level >= 0) {
      const int s = 1 << obstacle_level;
      obstacles = cv::Mat::zeros((k.height + s - 1) / s, (k.width + s - 1) / s, CV_8U);
      cv::rectangle(obstacles, cv::Rect(square_left.tl() / s, square_left.br() / s), cv::Scalar(255), cv::FILLED);
    }
    if (moving) {
      moving_mask = cv::Mat::zeros(k.height, k.width, CV_8U);
      moving_mask(square_left).setTo(255);
    }
    const sgd::PhotometricParams same;
    res.update(map, w, left1, right, k, camera(1.0), sgd::VerticalMisalignment(), {}, &same, obstacles, moving_mask);
    const sgd::GroundGrid cell = sgd::GroundGrid::covering(11.5, 11.5, 0.0, 0.0, 0.5);
    const sgd::GroundGrid near = sgd::GroundGrid::covering(8.0, 15.0, -3.0, 3.0, 0.5);
    cv::Mat layer = cv::Mat::zeros(near.rows, near.cols, CV_32F);
    const int unpublished = res.unpublishContradicted(near, {&layer});
    // NaN exactly where contradicted, only on the cells the square overlaps (x 11-12, y -0.5..0.5)
    EXPECT_EQ(unpublished, static_cast<int>(layer.total()) - cv::countNonZero(layer == layer));
    const cv::Mat named = res.contradicted(near);
    EXPECT_EQ(unpublished, cv::countNonZero(named));
    for (int v = 0; v < near.vertexCount(); ++v) {
      const Eigen::Vector2d p = near.position(v);
      if (named.at<uint8_t>(near.rowOf(v), near.colOf(v))) EXPECT_TRUE(p.x() >= 11.0 && p.x() <= 12.0 && std::abs(p.y()) <= 0.5);
    }
    return Cell{res.layer(sgd::PhotometricResidualMap::Layer::kOutlierRate, cell).at<float>(0, 0),
                res.layer(sgd::PhotometricResidualMap::Layer::kObservations, cell).at<float>(0, 0),
                res.contradicted(cell).at<uint8_t>(0, 0) != 0 ? 1 : 0};
  };
  // An object the ground does not explain (both pairs see it): an outlier, contradicted at 0.5.
  Cell c = run(false, -1, false);
  EXPECT_EQ(c.rate, 0.5f);
  EXPECT_EQ(c.observations, 2.0f);
  EXPECT_EQ(c.contradicted, 1);
  // ... seen through obstacle pixels (a mask at level 1, half size): the cell is not updated.
  c = run(false, 1, false);
  EXPECT_EQ(c.rate, 0.0f);
  EXPECT_EQ(c.observations, 1.0f);
  EXPECT_EQ(c.contradicted, 0);
  // Texture new on the ground (a shadow): the temporal pair flags it ...
  c = run(true, -1, false);
  EXPECT_EQ(c.rate, 0.5f);
  EXPECT_EQ(c.contradicted, 1);
  // ... unless it is known to have moved: the stereo pair alone explains it.
  c = run(true, -1, true);
  EXPECT_EQ(c.rate, 0.0f);
  EXPECT_EQ(c.observations, 2.0f);
  EXPECT_EQ(c.contradicted, 0);
  // A moving-texture mask does not excuse what the stereo pair refutes.
  c = run(false, -1, true);
  EXPECT_EQ(c.rate, 0.5f);
  // Masks must be CV_8U at a pyramid level of the left image; the threshold > 0 (> 1: none).
  sgd::PhotometricResidualMap res(0.5);
  EXPECT_THROW(res.update(map, w, image(camera(0.0)), image(right0), k, camera(0.0), sgd::VerticalMisalignment(), {},
                          nullptr, cv::Mat::zeros(100, 100, CV_8U)),
               std::invalid_argument);
  EXPECT_THROW(res.update(map, w, image(camera(0.0)), image(right0), k, camera(0.0), sgd::VerticalMisalignment(), {},
                          nullptr, cv::Mat(), cv::Mat::zeros(k.height, k.width, CV_32F)),
               std::invalid_argument);
  sgd::PhotometricResidualOptions o;
  std::string why;
  o.max_published_outlier_rate = 0.0;
  EXPECT_FALSE(o.isValid(&why));
  EXPECT_EQ(why, "max_published_outlier_rate must be > 0 (above 1: every height published)");
  o.max_published_outlier_rate = 1.5;
  EXPECT_TRUE(o.isValid(&why));
}
