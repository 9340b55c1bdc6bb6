// ElevationMap's archive: evicted tiles written to disk and loaded back unchanged, and every way
// an archive can be broken refused with the file's name.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "same_layer.hpp"
#include "stereo_ground_dem/ElevationMap.hpp"

using namespace stereo_ground_dem;
namespace fs = std::filesystem;

namespace {

class Archive : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sgd_test_archive_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  ElevationMapOptions options() const {
    ElevationMapOptions o;
    o.tile_size = 16;
    o.keep_radius_m = 30.0;
    o.archive_directory = dir_.string();
    return o;
  }

  /// A map with heights, information, observations and obstacles over 40 m x 20 m.
  ElevationMap filledMap() const {
    ElevationMap map(options());
    const GroundGrid w = GroundGrid::covering(-3.0, 37.0, -10.0, 10.0, 0.5);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> h(-0.3, 0.3), info(10.0, 1000.0);
    Eigen::VectorXd z(w.vertexCount()), inf(w.vertexCount()), obstacle_height(w.vertexCount());
    std::vector<uint8_t> update(static_cast<size_t>(w.vertexCount())), hit(update.size()), ground(update.size());
    for (int v = 0; v < w.vertexCount(); ++v) {
      z[v] = h(rng);
      inf[v] = info(rng);
      obstacle_height[v] = v % 7 == 0 ? 1.25 : NAN;
      update[static_cast<size_t>(v)] = v % 5 != 0;  // some vertices stay unknown
      hit[static_cast<size_t>(v)] = v % 7 == 0;
      ground[static_cast<size_t>(v)] = v % 11 == 0;
    }
    map.fuse(w, z, Eigen::VectorXd::Zero(w.vertexCount()), inf, update, 3);
    map.fuse(w, z, inf, inf, update, 4);
    map.updateObstacles(w, hit, ground, obstacle_height, 3);  // a mark needs two frames' evidence
    map.updateObstacles(w, hit, ground, obstacle_height, 4);
    return map;
  }

  fs::path dir_;
};

using test::sameLayer;

const ElevationMap::Layer kLayers[] = {ElevationMap::Layer::kElevation, ElevationMap::Layer::kVariance,
                                       ElevationMap::Layer::kObservations, ElevationMap::Layer::kLastUpdate,
                                       ElevationMap::Layer::kObstacle, ElevationMap::Layer::kObstacleHeight};
/// The layers that are NaN wherever the map publishes no height (obstacle "ground seen" included).
const ElevationMap::Layer kPerHeightLayers[] = {ElevationMap::Layer::kElevation, ElevationMap::Layer::kVariance,
                                                ElevationMap::Layer::kObservations, ElevationMap::Layer::kLastUpdate,
                                                ElevationMap::Layer::kObstacle};

}  // namespace

TEST_F(Archive, EvictedTilesRoundTripExactly) {
  ElevationMap map = filledMap();
  const GroundGrid bounds = map.bounds();
  const size_t tiles = map.tileCount();
  ASSERT_GT(tiles, 8u);
  std::vector<cv::Mat> before;
  for (auto l : kLayers) before.push_back(map.layer(l, bounds));
  // drive 1 km away: every tile is evicted to the archive
  EXPECT_EQ(map.evictFarFrom(1000.0, 0.0), static_cast<int>(tiles));
  EXPECT_EQ(map.tileCount(), 0u);
  size_t files = 0;
  for (const auto& f : fs::directory_iterator(dir_)) files += f.path().extension() == ".bin";
  EXPECT_EQ(files, tiles);
  // a foreign file in the archive folder is ignored
  std::ofstream(dir_ / "notes.txt") << "not a tile";
  ElevationMap back(options());
  EXPECT_EQ(back.loadArchive(dir_.string()), static_cast<int>(tiles));
  EXPECT_EQ(back.tileCount(), tiles);
  EXPECT_TRUE(back.bounds().sameLayout(bounds));
  for (size_t i = 0; i < before.size(); ++i) EXPECT_TRUE(sameLayer(back.layer(kLayers[i], bounds), before[i])) << i;
  // the known part is the same too
  EXPECT_TRUE(back.knownBounds().sameLayout(filledMap().knownBounds()));
  // loading into the map that evicted them restores it as well
  EXPECT_EQ(map.loadArchive(dir_.string()), static_cast<int>(tiles));
  for (size_t i = 0; i < before.size(); ++i) EXPECT_TRUE(sameLayer(map.layer(kLayers[i], bounds), before[i])) << i;
}

TEST_F(Archive, NegativeTileIndicesKeepTheirPlace) {
  ElevationMap map(options());
  const GroundGrid w = GroundGrid::covering(-50.0, -40.0, -30.0, -20.0, 0.5);
  map.fuse(w, Eigen::VectorXd::Constant(w.vertexCount(), 0.7), Eigen::VectorXd::Zero(w.vertexCount()),
           Eigen::VectorXd::Constant(w.vertexCount(), 50.0), std::vector<uint8_t>(static_cast<size_t>(w.vertexCount()), 1), 0);
  const cv::Mat before = map.layer(ElevationMap::Layer::kElevation, w);
  map.evictFarFrom(500.0, 500.0);
  ElevationMap back(options());
  back.loadArchive(dir_.string());
  EXPECT_TRUE(sameLayer(back.layer(ElevationMap::Layer::kElevation, w), before));
  EXPECT_FLOAT_EQ(back.layer(ElevationMap::Layer::kElevation, w).at<float>(3, 4), 0.7f);
}

TEST_F(Archive, BrokenArchivesAreRefusedNamingTheFile) {
  ElevationMap map = filledMap();
  map.evictFarFrom(1000.0, 0.0);
  const auto error = [&](const ElevationMapOptions& o) -> std::string {
    ElevationMap m(o);
    try {
      m.loadArchive(dir_.string());
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "<loaded>";
  };
  // another layout: tile size or resolution
  ElevationMapOptions other = options();
  other.tile_size = 32;
  EXPECT_NE(error(other).find("is not a tile of this map's layout"), std::string::npos);
  other = options();
  other.resolution_m = 0.25;
  EXPECT_NE(error(other).find("is not a tile of this map's layout"), std::string::npos);
  // a missing directory
  ElevationMap m(options());
  try {
    m.loadArchive((dir_ / "nowhere").string());
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "ElevationMap: cannot open archive directory '" + (dir_ / "nowhere").string() + "'");
  }
  // a truncated tile
  fs::path one;
  for (const auto& f : fs::directory_iterator(dir_))
    if (f.path().extension() == ".bin") one = f.path();
  fs::resize_file(one, fs::file_size(one) - 100);
  EXPECT_EQ(error(options()), "ElevationMap: archive tile '" + one.filename().string() + "' is truncated");
  // a header cut short and a wrong magic
  fs::resize_file(one, 10);
  EXPECT_EQ(error(options()), "ElevationMap: '" + one.filename().string() + "' is not a tile of this map's layout");
  std::ofstream(one, std::ios::binary) << std::string(64, 'x');
  EXPECT_EQ(error(options()), "ElevationMap: '" + one.filename().string() + "' is not a tile of this map's layout");
}

TEST_F(Archive, UnwritableArchiveDirectoryIsAnError) {
  ElevationMapOptions o = options();
  std::ofstream(dir_ / "file") << "x";
  o.archive_directory = (dir_ / "file" / "sub").string();  // below a regular file: cannot be created, even by root
  ElevationMap map(o);
  const GroundGrid w = GroundGrid::covering(0.0, 5.0, 0.0, 5.0, 0.5);
  map.fuse(w, Eigen::VectorXd::Zero(w.vertexCount()), Eigen::VectorXd::Zero(w.vertexCount()),
           Eigen::VectorXd::Ones(w.vertexCount()), std::vector<uint8_t>(static_cast<size_t>(w.vertexCount()), 1), 0);
  try {
    map.evictFarFrom(1000.0, 0.0);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("ElevationMap: cannot write archive tile '" + o.archive_directory + "/tile_", 0), 0u)
        << e.what();
  }
}

// The obstacle score (ElevationMapOptions::obstacle_*): one frame's evidence marks nothing, two
// frames' do; a freshly confirmed mark (a car that drove through) goes with one frame that sees
// the ground there, a long-standing one (capped at obstacle_max_score) with two.
TEST(ElevationMapObstacles, AMarkNeedsTwoFramesAndLongStandingMarksTwoGroundFrames) {
  ElevationMap map;
  const GroundGrid w = GroundGrid::covering(0.0, 5.0, 0.0, 5.0, 0.5);
  const int n = w.vertexCount();
  std::vector<uint8_t> update(static_cast<size_t>(n), 1), hit(update.size(), 0), ground(update.size(), 0),
      none(update.size(), 0);
  map.fuse(w, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Constant(n, 100.0), update, 0);
  const int a = w.index(2, 2), b = w.index(6, 6);
  hit[static_cast<size_t>(a)] = hit[static_cast<size_t>(b)] = 1;
  const Eigen::VectorXd height = Eigen::VectorXd::Constant(n, 1.2);
  auto marked = [&](int v) {
    const cv::Mat layer = map.layer(ElevationMap::Layer::kObstacle, w);
    return layer.at<float>(w.rowOf(v), w.colOf(v)) == 1.0f;
  };
  map.updateObstacles(w, hit, none, height, 1);
  EXPECT_FALSE(marked(a)) << "one frame's evidence";
  map.updateObstacles(w, hit, none, height, 2);
  EXPECT_TRUE(marked(a) && marked(b)) << "two frames' evidence";
  for (int f = 3; f < 6; ++f) {  // b keeps being seen: its score reaches the cap
    std::vector<uint8_t> only_b(update.size(), 0);
    only_b[static_cast<size_t>(b)] = 1;
    map.updateObstacles(w, only_b, none, height, f);
  }
  ground[static_cast<size_t>(a)] = ground[static_cast<size_t>(b)] = 1;
  map.updateObstacles(w, none, ground, height, 6);
  EXPECT_FALSE(marked(a)) << "a fresh mark goes with one frame that sees the ground";
  EXPECT_TRUE(marked(b)) << "a long-standing one needs two";
  map.updateObstacles(w, none, ground, height, 7);
  EXPECT_FALSE(marked(b));
  ElevationMapOptions bad;
  bad.obstacle_mark_score = 3.0;  // above the cap: nothing could ever be marked
  std::string why;
  EXPECT_FALSE(bad.isValid(&why));
  EXPECT_NE(why.find("max_score"), std::string::npos) << why;
}

TEST(ElevationMapLayers, AHeightFusedWithoutInformationIsPublishedAsUnknown) {
  // The frame's last linearization did not see the vertex and the map knew nothing there: the
  // height is kept for sample() (the estimator starts it as unknown: information 0), but no layer
  // publishes it, so that every published height has a variance.
  ElevationMap map;
  const GroundGrid w = GroundGrid::covering(0.0, 3.0, 0.0, 3.0, 0.5);
  const int n = w.vertexCount();
  const int a = w.index(2, 3), b = w.index(4, 1);
  std::vector<uint8_t> update(static_cast<size_t>(n), 1);
  Eigen::VectorXd data_info = Eigen::VectorXd::Constant(n, 400.0);
  data_info[a] = 0.0;
  map.fuse(w, Eigen::VectorXd::Constant(n, 0.3), Eigen::VectorXd::Zero(n), data_info, update, 4);
  Eigen::VectorXd h, info;
  map.sample(w, &h, &info);
  EXPECT_FLOAT_EQ(h[a], 0.3f);
  EXPECT_EQ(info[a], 0.0);
  for (const ElevationMap::Layer l : kPerHeightLayers) {
    const cv::Mat m = map.layer(l, w);
    EXPECT_TRUE(std::isnan(m.at<float>(w.rowOf(a), w.colOf(a)))) << static_cast<int>(l);
    EXPECT_TRUE(std::isfinite(m.at<float>(w.rowOf(b), w.colOf(b)))) << static_cast<int>(l);
  }
  EXPECT_FLOAT_EQ(map.layer(ElevationMap::Layer::kVariance, w).at<float>(w.rowOf(b), w.colOf(b)), 1.0f / 400.0f);
  // Measured later, it is published again.
  map.fuse(w, Eigen::VectorXd::Constant(n, 0.25), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Constant(n, 100.0), update, 5);
  EXPECT_FLOAT_EQ(map.layer(ElevationMap::Layer::kElevation, w).at<float>(w.rowOf(a), w.colOf(a)), 0.25f);
}

TEST_F(Archive, AHeightAFarRayRefutedIsPublishedAsUnknownUntilFusedAgain) {
  // A far ray (a pixel that saw past the surface) passed under what the map holds at `a`, and the
  // frame did not measure `a` again: sample() keeps the height (the estimator's start), the layers
  // publish it as unknown, the mark survives the archive and the next fusion clears it.
  ElevationMap map(options());
  const GroundGrid w = GroundGrid::covering(0.0, 3.0, 0.0, 3.0, 0.5);
  const int n = w.vertexCount();
  const int a = w.index(2, 3), b = w.index(4, 1), c = w.index(5, 5);
  std::vector<uint8_t> update(static_cast<size_t>(n), 1);
  map.fuse(w, Eigen::VectorXd::Constant(n, 0.8), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Constant(n, 400.0), update, 3);
  Eigen::VectorXd ceilings = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::infinity());
  ceilings[a] = 0.6;   // 0.2 m under the height: refuted
  ceilings[b] = 0.75;  // 0.05 m under it, within the 0.1 m margin: kept
  ceilings[c] = 0.2;   // far under it, but the frame measured c again: kept
  std::fill(update.begin(), update.end(), 0);
  update[static_cast<size_t>(c)] = 1;
  EXPECT_EQ(map.markRefuted(w, ceilings, 0.1, update), 1);
  EXPECT_EQ(map.markRefuted(w, ceilings, 0.1, update), 0) << "marked once";
  Eigen::VectorXd h, info;
  map.sample(w, &h, &info);
  EXPECT_FLOAT_EQ(h[a], 0.8f);
  EXPECT_FLOAT_EQ(info[a], 400.0f);
  const auto published = [&](const ElevationMap& m, int v) {
    return std::isfinite(m.layer(ElevationMap::Layer::kElevation, w).at<float>(w.rowOf(v), w.colOf(v)));
  };
  for (const ElevationMap::Layer l : kPerHeightLayers) {
    const cv::Mat m = map.layer(l, w);
    EXPECT_TRUE(std::isnan(m.at<float>(w.rowOf(a), w.colOf(a)))) << static_cast<int>(l);
    EXPECT_TRUE(std::isfinite(m.at<float>(w.rowOf(b), w.colOf(b)))) << static_cast<int>(l);
    EXPECT_TRUE(std::isfinite(m.at<float>(w.rowOf(c), w.colOf(c)))) << static_cast<int>(l);
  }
  // saved and loaded back (a map continued later): still refuted
  EXPECT_EQ(map.saveTiles(dir_.string()), static_cast<int>(map.tileCount()));
  ElevationMap back(options());
  back.loadArchive(dir_.string());
  EXPECT_FALSE(published(back, a));
  EXPECT_TRUE(published(back, b));
  // fused again: published again
  std::fill(update.begin(), update.end(), 1);
  map.fuse(w, Eigen::VectorXd::Constant(n, 0.5), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Constant(n, 100.0), update, 4);
  EXPECT_TRUE(published(map, a));
  EXPECT_THROW(map.markRefuted(w, Eigen::VectorXd::Zero(n - 1), 0.1, update), std::invalid_argument);
}
