// The ROS layer's conversion classes without a ROS graph (plain gtest): HeightGrid <-> DEM layers,
// traversability -> OccupancyGrid, mesh marker, camera_info / image validation, input monitor,
// motion covariance, the worker's frame slot, stamp checks, dynamic_reconfigure's parameter list.
#include <gtest/gtest.h>

#include <boost/any.hpp>
#include <map>
#include <set>

#include <cmath>
#include <limits>
#include <thread>

#include "stereo_ground_dem/DemParametersConfig.h"
#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/ros/DemDiagnostics.hpp"
#include "stereo_ground_dem/ros/HeightGridConverter.hpp"
#include "stereo_ground_dem/ros/PipelineParameters.hpp"
#include "stereo_ground_dem/ros/HeightMeshBuilder.hpp"
#include "stereo_ground_dem/ros/ImageMessageConverter.hpp"
#include "stereo_ground_dem/ros/InputMonitor.hpp"
#include "stereo_ground_dem/ros/LatestFrameSlot.hpp"
#include "stereo_ground_dem/ros/MotionCovariance.hpp"
#include "stereo_ground_dem/ros/StampSequenceChecker.hpp"
#include "stereo_ground_dem/ros/StartHoldPolicy.hpp"
#include "stereo_ground_dem/ros/StereoInputValidator.hpp"
#include "stereo_ground_dem/ros/TraversabilityCostTable.hpp"

using namespace stereo_ground_dem;

namespace {
const float kNaN = std::numeric_limits<float>::quiet_NaN();

GroundGrid smallGrid() {
  GroundGrid g;
  g.resolution_m = 0.5;
  g.row0 = -3;
  g.col0 = 4;
  g.rows = 5;
  g.cols = 7;
  return g;
}

sensor_msgs::CameraInfo info(double fx, double tx, unsigned w = 640, unsigned h = 480) {
  sensor_msgs::CameraInfo c;
  c.width = w;
  c.height = h;
  c.P = {fx, 0, 320, tx, 0, fx, 240, 0, 0, 0, 1, 0};
  return c;
}

sensor_msgs::Image image(const std::string& encoding, unsigned w = 640, unsigned h = 480) {
  sensor_msgs::Image m;
  m.encoding = encoding;
  m.width = w;
  m.height = h;
  m.step = w * (encoding == "bgr8" || encoding == "rgb8" ? 3 : encoding == "mono16" ? 2 : 1);
  m.data.assign(static_cast<size_t>(m.step) * h, 100);
  return m;
}
}  // namespace

TEST(HeightGridConverter, RoundTripAndGridMapIndexing) {
  const GroundGrid g = smallGrid();
  cv::Mat e(g.rows, g.cols, CV_32F);
  for (int r = 0; r < g.rows; ++r)
    for (int c = 0; c < g.cols; ++c) e.at<float>(r, c) = static_cast<float>(g.xOfCol(c) + 100 * g.yOfRow(r));
  e.at<float>(1, 2) = kNaN;
  std_msgs::Header h;
  h.frame_id = "odom";
  const HeightGrid m = HeightGridConverter::toMessage(g, {{"elevation", e}}, h);
  EXPECT_DOUBLE_EQ(m.info.length_x, 3.5);
  EXPECT_DOUBLE_EQ(m.info.length_y, 2.5);
  ASSERT_EQ(m.data.size(), 1u);
  EXPECT_EQ(m.data[0].layout.dim[0].label, "column_index");
  // grid_map cell (i, j) = data[j * nx + i], centred at x = px + lx/2 - res/2 - i res, same for y
  const int nx = g.cols;
  for (int i = 0; i < g.cols; ++i)
    for (int j = 0; j < g.rows; ++j) {
      const double x = m.info.pose.position.x + m.info.length_x / 2 - 0.25 - i * 0.5;
      const double y = m.info.pose.position.y + m.info.length_y / 2 - 0.25 - j * 0.5;
      const float v = m.data[0].data[static_cast<size_t>(j * nx + i)];
      if (std::isnan(v)) {
        EXPECT_NEAR(x, g.xOfCol(2), 1e-9);
        EXPECT_NEAR(y, g.yOfRow(1), 1e-9);
      } else {
        EXPECT_NEAR(v, x + 100 * y, 1e-3);
      }
    }
  GroundGrid g2;
  std::vector<GridLayer> layers;
  std::string why;
  ASSERT_TRUE(HeightGridConverter::fromMessage(m, &g2, &layers, &why)) << why;
  EXPECT_TRUE(g2.sameLayout(g));
  ASSERT_EQ(layers.size(), 1u);
  EXPECT_EQ(cv::norm(layers[0].values, e, cv::NORM_INF, e == e), 0.0);
}

TEST(TraversabilityCostTable, ValuesAndObstacles) {
  const TraversabilityCostTable t;
  EXPECT_EQ(t.occupancy(1.0f), 0);
  EXPECT_EQ(t.occupancy(0.0f), 100);
  EXPECT_EQ(t.occupancy(kNaN), -1);
  EXPECT_NEAR(t.occupancy(0.5f), 50, 1);
  EXPECT_LE(t.occupancy(0.001f), 100);
  const GroundGrid g = smallGrid();
  cv::Mat trav(g.rows, g.cols, CV_32F, cv::Scalar(1.0f)), obs(g.rows, g.cols, CV_32F, cv::Scalar(3.0f));
  cv::Mat obstacle(g.rows, g.cols, CV_32F, cv::Scalar(0.0f));
  trav.at<float>(0, 0) = kNaN;
  obs.at<float>(0, 1) = 0.0f;
  obstacle.at<float>(2, 3) = 1.0f;
  obstacle.at<float>(4, 6) = 1.0f;
  trav.at<float>(4, 6) = kNaN;  // hidden ground under an obstacle: still lethal
  obs.at<float>(4, 6) = kNaN;
  const nav_msgs::OccupancyGrid o = t.toOccupancyGrid(g, trav, obs, 1, std_msgs::Header(), obstacle);
  ASSERT_EQ(o.data.size(), 35u);
  EXPECT_EQ(o.data[0], -1);
  EXPECT_EQ(o.data[1], -1);
  EXPECT_EQ(o.data[2], 0);
  EXPECT_EQ(o.data[2 * 7 + 3], 100);
  EXPECT_EQ(o.data[4 * 7 + 6], 100);
  EXPECT_DOUBLE_EQ(o.info.origin.position.x, g.x0() - 0.25);
  EXPECT_DOUBLE_EQ(o.info.origin.position.y, g.y0() - 0.25);
  // Uncertain cells unknown: P 0.6 (certainty 0.6) and 0.3 (0.7) below 0.8; P 0.95 and 0.05 kept;
  // an obstacle stays lethal whatever P says.
  cv::Mat p(g.rows, g.cols, CV_32F, cv::Scalar(0.95f));
  p.at<float>(0, 2) = 0.6f;
  p.at<float>(0, 3) = 0.3f;
  p.at<float>(0, 4) = 0.05f;
  p.at<float>(2, 3) = 0.5f;
  const nav_msgs::OccupancyGrid q = t.toOccupancyGrid(g, trav, obs, 1, std_msgs::Header(), obstacle, p, 0.8);
  EXPECT_EQ(q.data[2], -1);
  EXPECT_EQ(q.data[3], -1);
  EXPECT_EQ(q.data[4], o.data[4]);
  EXPECT_EQ(q.data[5], o.data[5]);
  EXPECT_EQ(q.data[2 * 7 + 3], 100);
  // 0 (or anything up to 0.5): off
  EXPECT_EQ(t.toOccupancyGrid(g, trav, obs, 1, std_msgs::Header(), obstacle, p, 0.0).data, o.data);
  EXPECT_THROW(t.toOccupancyGrid(g, trav, obs, 1, std_msgs::Header(), obstacle, cv::Mat(2, 2, CV_32F), 0.8),
               std::invalid_argument);
}

TEST(HeightMeshBuilder, OnlyKnownTrianglesNoNaN) {
  const GroundGrid g = smallGrid();
  cv::Mat e(g.rows, g.cols, CV_32F, cv::Scalar(0.1f));
  e.at<float>(2, 2) = kNaN;
  HeightMeshOptions opt;
  const visualization_msgs::Marker m = HeightMeshBuilder::build(g, e, std_msgs::Header(), opt);
  EXPECT_EQ(m.type, visualization_msgs::Marker::TRIANGLE_LIST);
  EXPECT_EQ(m.points.size(), static_cast<size_t>(3 * (g.triangleCount() - 6)));  // 6 triangles touch (2,2)
  EXPECT_EQ(m.colors.size(), m.points.size());
  for (const auto& p : m.points) EXPECT_TRUE(std::isfinite(p.z));
}

TEST(HeightMeshBuilder, GreyFromTheIntensityLayer) {
  const GroundGrid g = smallGrid();
  cv::Mat e(g.rows, g.cols, CV_32F, cv::Scalar(0.1f));
  cv::Mat in(g.rows, g.cols, CV_32F, cv::Scalar(51.0f));
  in.at<float>(0, 0) = kNaN;  // unknown grey: the height colour
  HeightMeshOptions opt;
  const visualization_msgs::Marker heights = HeightMeshBuilder::build(g, e, std_msgs::Header(), opt, &in);
  opt.colors = MeshColors::kIntensity;
  const visualization_msgs::Marker grey = HeightMeshBuilder::build(g, e, std_msgs::Header(), opt, &in);
  ASSERT_EQ(grey.colors.size(), heights.colors.size());
  int grey_vertices = 0;
  for (size_t i = 0; i < grey.points.size(); ++i) {
    const bool origin = grey.points[i].x == g.x0() && grey.points[i].y == g.y0();
    if (origin) {
      EXPECT_EQ(grey.colors[i].r, heights.colors[i].r);
      continue;
    }
    EXPECT_FLOAT_EQ(grey.colors[i].r, 0.2f);
    EXPECT_FLOAT_EQ(grey.colors[i].g, 0.2f);
    EXPECT_FLOAT_EQ(grey.colors[i].b, 0.2f);
    ++grey_vertices;
  }
  EXPECT_GT(grey_vertices, 0);
  const cv::Mat wrong(2, 2, CV_32F, cv::Scalar(1.0f));
  EXPECT_THROW(HeightMeshBuilder::build(g, e, std_msgs::Header(), opt, &wrong), std::invalid_argument);
}

// ~mesh_colors: residual: green at 0, yellow at half of residual_max_grey, red at and above it,
// mid-grey where unknown; a residual layer of another size is refused.
TEST(HeightMeshBuilder, ResidualColoursGreenToRed) {
  const GroundGrid g = smallGrid();
  cv::Mat e(g.rows, g.cols, CV_32F, cv::Scalar(0.1f));
  cv::Mat res(g.rows, g.cols, CV_32F, cv::Scalar(10.0f));  // half of 20: yellow
  res.at<float>(0, 0) = kNaN;
  res.at<float>(g.rows - 1, g.cols - 1) = 45.0f;  // beyond the maximum: red
  res.at<float>(0, g.cols - 1) = 0.0f;            // green
  HeightMeshOptions opt;
  opt.colors = MeshColors::kResidual;
  const visualization_msgs::Marker m = HeightMeshBuilder::build(g, e, std_msgs::Header(), opt, nullptr, &res);
  ASSERT_EQ(m.colors.size(), m.points.size());
  int seen[4] = {0, 0, 0, 0};  // unknown, red, green, yellow
  for (size_t i = 0; i < m.points.size(); ++i) {
    const auto& p = m.points[i];
    const auto& k = m.colors[i];
    if (p.x == g.x0() && p.y == g.y0()) {
      EXPECT_FLOAT_EQ(k.r, 0.5f);
      EXPECT_FLOAT_EQ(k.g, 0.5f);
      EXPECT_FLOAT_EQ(k.b, 0.5f);
      ++seen[0];
    } else if (p.x == g.xOfCol(g.cols - 1) && p.y == g.yOfRow(g.rows - 1)) {
      EXPECT_FLOAT_EQ(k.r, 1.0f);
      EXPECT_FLOAT_EQ(k.g, 0.0f);
      ++seen[1];
    } else if (p.x == g.xOfCol(g.cols - 1) && p.y == g.y0()) {
      EXPECT_FLOAT_EQ(k.r, 0.0f);
      EXPECT_FLOAT_EQ(k.g, 1.0f);
      ++seen[2];
    } else {
      EXPECT_FLOAT_EQ(k.r, 1.0f);
      EXPECT_FLOAT_EQ(k.g, 1.0f);
      EXPECT_FLOAT_EQ(k.b, 0.0f);
      ++seen[3];
    }
  }
  for (int n : seen) EXPECT_GT(n, 0);
  const cv::Mat wrong(2, 2, CV_32F, cv::Scalar(1.0f));
  EXPECT_THROW(HeightMeshBuilder::build(g, e, std_msgs::Header(), opt, nullptr, &wrong), std::invalid_argument);
}

TEST(StereoInputValidator, CameraInfoAndEncodings) {
  StereoInputValidator v;
  const auto l = info(500, 0), r = info(500, -500 * 0.54);
  StereoInputCheck c = v.check(image("mono8"), l, image("mono8"), r);
  ASSERT_TRUE(c.ok) << c.problem;
  EXPECT_NEAR(c.rig.baseline_m, 0.54, 1e-12);
  EXPECT_EQ(c.rig.width, 640);
  for (const char* e : {"mono16", "bgr8", "rgb8"}) EXPECT_TRUE(v.check(image(e), l, image(e), r).ok) << e;
  c = v.check(image("bayer_rggb8"), l, image("bayer_rggb8"), r);
  EXPECT_FALSE(c.ok);
  EXPECT_NE(c.problem.find("Bayer"), std::string::npos) << c.problem;
  EXPECT_NE(v.check(image("32FC1"), l, image("32FC1"), r).problem.find("not supported"), std::string::npos);
  EXPECT_NE(v.check(image("mono8"), l, image("mono8", 639), r).problem.find("639x480"), std::string::npos);
  EXPECT_FALSE(v.check(image("mono8"), l, image("bgr8"), r).ok);
  EXPECT_NE(v.check(image("mono8"), l, image("mono8"), info(501, -501 * 0.54)).problem.find("camera_info"),
            std::string::npos);
  EXPECT_FALSE(v.check(image("mono8"), l, image("mono8"), info(500, 0)).ok);  // no baseline
  EXPECT_FALSE(v.check(image("mono8"), sensor_msgs::CameraInfo(), image("mono8"), r).ok);
}

TEST(InputMonitor, NamesSilentTopicsAndGaps) {
  InputMonitor m({"L", "LI", "R", "RI"}, false, 0.01);
  EXPECT_NE(m.check().find("no input"), std::string::npos);
  m.count(InputMonitor::kLeftImage, 1.0);
  m.count(InputMonitor::kRightImage, 1.0);
  m.count(InputMonitor::kRightInfo, 1.0);
  const std::string s = m.check();
  EXPECT_NE(s.find("nothing on LI"), std::string::npos) << s;
  m.countSynchronized();
  EXPECT_EQ(m.check(), "");
  EXPECT_EQ(m.frameGap(10.0), "");
  EXPECT_EQ(m.frameGap(10.1), "");
  EXPECT_EQ(m.frameGap(10.2), "");
  EXPECT_EQ(m.frameGap(10.3), "");
  const std::string gap = m.frameGap(11.0);
  EXPECT_NE(gap.find("6 frames"), std::string::npos) << gap;
  EXPECT_EQ(m.frameGap(11.1), "");
}

TEST(MotionCovariance, InverseFallbackAndFrameChange) {
  Matrix6d info = Matrix6d::Identity() * 100.0;
  bool fb = true;
  const Matrix6d cov = MotionCovariance::fromInformation(info, MotionCovariance::diagonal(1, 1), &fb);
  EXPECT_FALSE(fb);
  EXPECT_NEAR(cov(0, 0), 0.01, 1e-12);
  MotionCovariance::fromInformation(Matrix6d::Zero(), MotionCovariance::diagonal(1, 1), &fb);
  EXPECT_TRUE(fb);
  // a pure rotation of the frame permutes the translational variances
  Matrix6d c = Matrix6d::Zero();
  c.diagonal() << 1, 2, 3, 4, 5, 6;
  Eigen::Isometry3d b_T_c = Eigen::Isometry3d::Identity();
  b_T_c.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;  // optical camera in base_link
  const Matrix6d cb = MotionCovariance::changeFrame(c, b_T_c);
  EXPECT_NEAR(cb(0, 0), 3, 1e-12);  // base x = camera z
  EXPECT_NEAR(cb(1, 1), 1, 1e-12);
  EXPECT_NEAR(cb(2, 2), 2, 1e-12);
}

TEST(StereoInputValidator, NaNCameraInfoAndGenericEncodings) {
  StereoInputValidator v;
  auto l = info(500, 0), r = info(500, -500 * 0.54);
  l.P[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(v.check(image("mono8"), l, image("mono8"), r).problem,
            "camera_info: left camera_info P[2] is nan: the calibration is broken (NaN or infinite projection matrix)");
  const auto good = info(500, 0);
  sensor_msgs::Image be = image("16UC1");
  be.step = 640 * 2;
  be.data.assign(static_cast<size_t>(be.step) * 480, 1);
  be.is_bigendian = 1;
  EXPECT_EQ(v.check(be, good, be, r).problem,
            "left image: encoding '16UC1' is a generic (depth-image) encoding, not a grey image: publish mono8 or "
            "mono16 (or remap the camera's image_rect, not a depth image)");
  // inconsistent pair: different focal lengths
  EXPECT_NE(v.check(image("mono8"), good, image("mono8"), info(510, -510 * 0.54)).problem.find("camera_info"),
            std::string::npos);
}

TEST(ImageMessageConverter, SharesOrSwapsBytes) {
  sensor_msgs::Image m = image("mono16", 4, 2);
  for (size_t i = 0; i < m.data.size(); i += 2) {  // value 0x0102 + i in big-endian byte order
    m.data[i] = 0x01;
    m.data[i + 1] = static_cast<uint8_t>(0x02 + i);
  }
  m.is_bigendian = 1;
  const cv::Mat big = ImageMessageConverter::toMat(m);
  ASSERT_EQ(big.type(), CV_16UC1);
  EXPECT_EQ(big.at<uint16_t>(0, 0), 0x0102);
  EXPECT_EQ(big.at<uint16_t>(1, 3), 0x0102 + 14);
  EXPECT_NE(big.data, m.data.data());  // swapped copy
  m.is_bigendian = 0;
  const cv::Mat little = ImageMessageConverter::toMat(m);
  EXPECT_EQ(little.at<uint16_t>(0, 0), 0x0201);
  EXPECT_EQ(little.data, m.data.data());  // shared, no copy
  const sensor_msgs::Image c = image("bgr8", 5, 3);
  const cv::Mat bgr = ImageMessageConverter::toMat(c);
  EXPECT_EQ(bgr.type(), CV_8UC3);
  EXPECT_EQ(bgr.data, c.data.data());
  EXPECT_THROW(ImageMessageConverter::toMat(image("bayer_rggb8")), std::invalid_argument);
}

TEST(LatestFrameSlot, HoldsTheFrameAfterAnInitialization) {
  // While the initializing frame is processed, the first frame that arrives is held and later ones
  // are dropped; once it is taken, the slot keeps the newest again.
  LatestFrameSlot<int> slot;
  slot.holdNext();
  EXPECT_FALSE(slot.put(1).has_value());
  std::optional<int> dropped = slot.put(2);
  ASSERT_TRUE(dropped.has_value());
  EXPECT_EQ(*dropped, 2);  // the newcomer is dropped, 1 is held
  EXPECT_EQ(*slot.put(3), 3);
  int v = 0;
  EXPECT_EQ(slot.take(&v), LatestFrameSlot<int>::Taken::kItem);
  EXPECT_EQ(v, 1);
  EXPECT_FALSE(slot.put(4).has_value());
  dropped = slot.put(5);  // holding ended with the take: 4 is replaced
  ASSERT_TRUE(dropped.has_value());
  EXPECT_EQ(*dropped, 4);
  EXPECT_EQ(slot.take(&v), LatestFrameSlot<int>::Taken::kItem);
  EXPECT_EQ(v, 5);
  EXPECT_EQ(slot.puts(), 5);
}

TEST(StartHoldPolicy, HoldsAfterFramesWithoutVelocityAndTheFirstFewWithOne) {
  // (initialized, velocity known) before each frame: initializing, first tracked, then tracked
  // with a velocity; a failure (velocity lost) starts over.
  StartHoldPolicy two(2);
  EXPECT_TRUE(two.holdNext(false, false));  // initializes
  EXPECT_TRUE(two.holdNext(true, false));   // first tracked: motion search
  EXPECT_TRUE(two.holdNext(true, true));    // velocity from one step
  EXPECT_TRUE(two.holdNext(true, true));
  EXPECT_FALSE(two.holdNext(true, true));   // steady: the newest frame
  EXPECT_FALSE(two.holdNext(true, true));
  EXPECT_TRUE(two.holdNext(true, false));   // after a failure
  EXPECT_TRUE(two.holdNext(true, true));
  EXPECT_TRUE(two.holdNext(true, true));
  EXPECT_FALSE(two.holdNext(true, true));
  StartHoldPolicy none(0);  // as before 2026-12-03: only the frames without a velocity
  EXPECT_TRUE(none.holdNext(false, false));
  EXPECT_TRUE(none.holdNext(true, false));
  EXPECT_FALSE(none.holdNext(true, true));
  EXPECT_TRUE(none.holdNext(false, false));  // a reset
}

TEST(LatestFrameSlot, KeepsOnlyTheNewest) {
  LatestFrameSlot<int> slot;
  EXPECT_FALSE(slot.put(1).has_value());
  const std::optional<int> dropped = slot.put(2);  // 1 was not taken: replaced, handed back
  ASSERT_TRUE(dropped.has_value());
  EXPECT_EQ(*dropped, 1);
  int v = 0;
  EXPECT_EQ(slot.take(&v), LatestFrameSlot<int>::Taken::kItem);
  EXPECT_EQ(v, 2);
  EXPECT_FALSE(slot.occupied());
  slot.wake();
  EXPECT_EQ(slot.take(&v), LatestFrameSlot<int>::Taken::kWoken);
  slot.put(3);
  slot.wake();  // an item and a wake-up: the item first, then the wake-up
  EXPECT_EQ(slot.take(&v), LatestFrameSlot<int>::Taken::kItem);
  EXPECT_EQ(v, 3);
  EXPECT_EQ(slot.take(&v), LatestFrameSlot<int>::Taken::kWoken);
  EXPECT_EQ(slot.puts(), 3);
  slot.put(4);
  slot.close();
  EXPECT_EQ(slot.take(&v), LatestFrameSlot<int>::Taken::kClosed);  // pending item discarded
  EXPECT_TRUE(slot.put(5).has_value());                             // nobody will take it
}

TEST(LatestFrameSlot, CloseEndsABlockedTake) {
  LatestFrameSlot<int> slot;
  LatestFrameSlot<int>::Taken result = LatestFrameSlot<int>::Taken::kItem;
  std::thread consumer([&] {
    int v = 0;
    result = slot.take(&v);
  });
  slot.close();
  consumer.join();
  EXPECT_EQ(result, LatestFrameSlot<int>::Taken::kClosed);
}

TEST(StampSequenceChecker, Verdicts) {
  using V = StampSequenceChecker::Verdict;
  StampSequenceChecker s(0.05, 2.0);
  EXPECT_EQ(s.check(0.0).message,
            "the images have no time stamp (header.stamp is 0): the estimator needs capture times");
  EXPECT_EQ(s.check(100.0).verdict, V::kAccept);
  EXPECT_EQ(s.check(100.1).verdict, V::kAccept);
  StampSequenceChecker::Result r = s.check(100.1);
  EXPECT_EQ(r.verdict, V::kSkip);
  EXPECT_EQ(r.message, "duplicate time stamp: the frame has the same stamp as the previous one");
  r = s.check(100.07);
  EXPECT_EQ(r.verdict, V::kSkip);
  EXPECT_EQ(r.message, "time stamp goes backwards by 0.030 s (frames out of order)");
  EXPECT_EQ(s.check(100.2).verdict, V::kAccept);  // the skipped frames did not move the reference
  r = s.check(99.0);
  EXPECT_EQ(r.verdict, V::kRestart);
  EXPECT_EQ(r.message, "time jumped back by 1.200 s (bag restarted or looped?): starting a new map");
  EXPECT_EQ(s.check(99.1).verdict, V::kAccept);  // the restart is the new reference
  EXPECT_EQ(s.check(100.5).verdict, V::kAccept);  // a 1.4 s gap is bridged by the prediction
  r = s.check(103.0);
  EXPECT_EQ(r.verdict, V::kRestart);
  EXPECT_EQ(r.message,
            "time jumped forward by 2.500 s (more than ~max_stamp_gap_s 2.000 s; the motion over the gap is unknown): "
            "starting a new map");
}

// cfg/DemParameters.cfg is written by hand: it must offer exactly the ParameterTable entries
// flagged tunable, with their types and defaults, and ranges that hold the defaults (17 tunable
// estimator parameters were missing from it until 2026-12-01).
TEST(PipelineParameters, ReconfigureOffersExactlyTheTunableParameters) {
  PipelineOptions defaults;
  const ParameterTable table(&defaults);
  std::map<std::string, const ParameterTable::Entry*> tunable;
  for (const auto& e : table.entries())
    if (e.tunable) tunable[e.name] = &e;
  const auto& dflt = DemParametersConfig::__getDefault__();
  const auto& lo = DemParametersConfig::__getMin__();
  const auto& hi = DemParametersConfig::__getMax__();
  auto number = [](const std::string& type, const boost::any& v) {
    if (type == "double") return boost::any_cast<double>(v);
    if (type == "int") return static_cast<double>(boost::any_cast<int>(v));
    return boost::any_cast<bool>(v) ? 1.0 : 0.0;
  };
  std::set<std::string> offered;
  for (const auto& d : DemParametersConfig::__getParamDescriptions__()) {
    offered.insert(d->name);
    const auto it = tunable.find(d->name);
    if (it == tunable.end()) {
      ADD_FAILURE() << d->name << " is in cfg/DemParameters.cfg but not a tunable ParameterTable entry";
      continue;
    }
    const ParameterTable::Type t = it->second->type;
    const std::string want = t == ParameterTable::Type::kDouble ? "double" : t == ParameterTable::Type::kInt ? "int" : "bool";
    EXPECT_EQ(d->type, want) << d->name;
    if (d->type != want) continue;
    boost::any v, vlo, vhi;
    d->getValue(dflt, v);
    d->getValue(lo, vlo);
    d->getValue(hi, vhi);
    EXPECT_EQ(number(d->type, v), table.get(*it->second)) << d->name << ": the cfg default is not the table's";
    if (d->type != "bool") {
      EXPECT_LE(number(d->type, vlo), number(d->type, v)) << d->name;
      EXPECT_GE(number(d->type, vhi), number(d->type, v)) << d->name;
    }
  }
  for (const auto& kv : tunable) EXPECT_TRUE(offered.count(kv.first)) << kv.first << " is tunable but not in cfg/DemParameters.cfg";
  // and the node's copy by name finds every one of them
  PipelineOptions copy;
  EXPECT_TRUE(PipelineParameters::fromConfig(dflt, &copy).empty());
}

// /diagnostics shows what the estimator's own guards did: pre-alignments beyond the acceleration
// bound (the prediction kept) and moving texture carried from the last two frames, counted and
// with the last frame's values; a frame without them resets the last values, not the counts.
TEST(DemDiagnostics, ShowsRejectedPreAlignmentsAndCarriedMovingTexture) {
  DemDiagnostics d("sgd_test", {"L", "LI", "R", "RI"}, false, 0.01);
  DemDiagnostics::FrameRecord r;
  r.prealign_shift_m = 0.42;
  r.prealign_rejected = true;
  r.carried_moving_pixels = 137;
  r.repeat_from_prediction = true;
  d.processed(r);
  r.repeat_from_prediction = false;
  r.prealign_shift_m = 0.05;
  r.prealign_rejected = false;
  r.prealign_discarded = 3;  // three other starts ended beyond the bound
  r.carried_moving_pixels = 0;
  d.processed(r);
  r.prealign_discarded = 0;
  r.prealign_shift_m = 0.61;
  r.prealign_rejected = true;
  r.carried_moving_pixels = 12;
  r.hidden_pixels = 345;
  r.far_pixels = 67;
  r.far_seeded_vertices = 8;
  r.rising_seeded_vertices = 13;
  d.processed(r);
  const DemDiagnostics::Counts c = d.counts();
  EXPECT_EQ(c.processed, 3);
  EXPECT_EQ(c.tracked, 3);
  EXPECT_EQ(c.prealign_rejected, 2);
  EXPECT_EQ(c.prealign_discarded, 1);
  EXPECT_EQ(c.carried_moving, 2);
  EXPECT_EQ(c.repeat_from_prediction, 1);
  diagnostic_updater::DiagnosticStatusWrapper stat;
  d.diagnose(stat);
  std::map<std::string, std::string> kv;
  for (const auto& v : stat.values) kv[v.key] = v.value;
  EXPECT_EQ(kv["pre-alignment beyond max_acceleration_mps2 (prediction kept)"], "2");
  EXPECT_EQ(kv["frames with pre-alignment starts beyond max_acceleration_mps2 (not candidates)"], "1");
  EXPECT_EQ(std::stod(kv["pre-alignment shift from the prediction last [m]"]), 0.61);
  EXPECT_EQ(kv["frames skipping moving texture carried from the last two"], "2");
  EXPECT_EQ(kv["moving texture carried last [px at the test level]"], "12");
  EXPECT_EQ(kv["frames whose second temporal pass started from the prediction (moving texture pulled the first)"], "1");
  EXPECT_EQ(kv["ground the previous camera did not see, last [px at the finest temporal level]"], "345");
  EXPECT_EQ(kv["ground seen past the surface, last (excluded) [px at the obstacle test level]"], "67");
  EXPECT_EQ(kv["vertices started from ground seen past the surface, last"], "8");
  EXPECT_EQ(kv["vertices started on ground rising out of the surface, last"], "13");
  r.carried_moving_pixels = 0;
  r.prealign_shift_m = std::numeric_limits<double>::quiet_NaN();
  r.prealign_rejected = false;
  d.processed(r);
  diagnostic_updater::DiagnosticStatusWrapper stat2;
  d.diagnose(stat2);
  kv.clear();
  for (const auto& v : stat2.values) kv[v.key] = v.value;
  EXPECT_EQ(kv["moving texture carried last [px at the test level]"], "0");
  EXPECT_EQ(kv["pre-alignment beyond max_acceleration_mps2 (prediction kept)"], "2");
  EXPECT_EQ(kv["pre-alignment shift from the prediction last [m]"].find("nan"), 0u) << kv["pre-alignment shift from the prediction last [m]"];
}
