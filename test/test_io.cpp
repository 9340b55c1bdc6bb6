// Tests of the io library: GeoTIFF, dem.yaml, KITTI disparity PNG, pictures, PLY, trajectories.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "stereo_ground_dem/GreyConverter.hpp"
#include "stereo_ground_dem/io/AllocatorTuning.hpp"
#include "stereo_ground_dem/io/DemExporter.hpp"
#include "stereo_ground_dem/io/DemMetadata.hpp"
#include "stereo_ground_dem/io/ImageFileReader.hpp"
#include "stereo_ground_dem/io/KittiSequence.hpp"
#include "stereo_ground_dem/io/DemPicture.hpp"
#include "stereo_ground_dem/io/DisparityPng.hpp"
#include "stereo_ground_dem/io/GeoTiff.hpp"
#include "stereo_ground_dem/io/NumberText.hpp"
#include "stereo_ground_dem/io/PlyWriter.hpp"
#include "stereo_ground_dem/io/TrajectoryWriter.hpp"

namespace sgd = stereo_ground_dem;
namespace fs = std::filesystem;

namespace {

const float kNan = std::numeric_limits<float>::quiet_NaN();

/// A fresh directory per test, removed at the end.
class IoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("sgd_test_io_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

void spit(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream is(text);
  std::string l;
  while (std::getline(is, l)) out.push_back(l);
  return out;
}

sgd::GroundGrid makeGrid(double res, int row0, int col0, int rows, int cols) {
  sgd::GroundGrid g;
  g.resolution_m = res;
  g.row0 = row0;
  g.col0 = col0;
  g.rows = rows;
  g.cols = cols;
  return g;
}

Eigen::Isometry3d somePose(double a, double b, double c, const Eigen::Vector3d& t) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.linear() =
      (Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(b, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(c, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  p.translation() = t;
  return p;
}

template <typename F>
std::string thrownMessage(F f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "<nothing thrown>";
}

// ------------------------------------------------------------------------------- AllocatorTuning
/// Runs `body` in a forked child and returns what it returned; -1 if the child failed.
long inChild(const std::function<long()>& body) {
  int fds[2];
  if (pipe(fds) != 0) return -1;
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    const long result = body();
    const ssize_t written = write(fds[1], &result, sizeof(result));
    std::_Exit(written == static_cast<ssize_t>(sizeof(result)) ? 0 : 1);
  }
  close(fds[1]);
  long result = -1;
  if (pid < 0 || read(fds[0], &result, sizeof(result)) != static_cast<ssize_t>(sizeof(result))) result = -1;
  close(fds[0]);
  if (pid > 0) waitpid(pid, nullptr, 0);
  return result;
}

/// Page faults of 9 more passes of a frame-like allocation pattern (34 MB in six blocks of 0.3-9
/// MB, written, then freed) after a first pass, in a forked child with or without the tuning; -1 if
/// the child failed.
long repeatedPassFaults(bool tuned) {
  return inChild([tuned]() -> long {
    if (tuned && !sgd::AllocatorTuning::apply()) return -1;
    auto pass = [] {
      std::vector<void*> blocks;
      for (size_t bytes : {size_t{300} << 10, size_t{2} << 20, size_t{5} << 20, size_t{9} << 20, size_t{9} << 20,
                           size_t{9} << 20}) {
        void* p = std::malloc(bytes);
        if (p == nullptr) std::_Exit(1);
        std::memset(p, 1, bytes);
        blocks.push_back(p);
      }
      for (void* p : blocks) std::free(p);
    };
    pass();
    rusage before{}, after{};
    getrusage(RUSAGE_SELF, &before);
    for (int i = 0; i < 9; ++i) pass();
    getrusage(RUSAGE_SELF, &after);
    return after.ru_minflt - before.ru_minflt;
  });
}

/// Resident pages of this process (/proc/self/statm); -1 if unreadable.
long residentPages() {
  std::ifstream in("/proc/self/statm");
  long size = 0, resident = -1;
  in >> size >> resident;
  return in ? resident : -1;
}

/// Resident KiB given back by releaseFreeMemory() in a tuned child after 32 MiB of 16 KiB blocks
/// were written and freed below a block still in use (so the heap top cannot shrink); -1 on failure.
long releasedKib() {
  return inChild([]() -> long {
    if (!sgd::AllocatorTuning::apply()) return -1;
    std::vector<void*> blocks;
    for (int i = 0; i < 2048; ++i) {
      void* p = std::malloc(16 << 10);
      if (p == nullptr) std::_Exit(1);
      std::memset(p, 1, 16 << 10);
      blocks.push_back(p);
    }
    void* pin = std::malloc(64);  // above them: the free blocks are not the heap top
    for (void* p : blocks) std::free(p);
    const long before = residentPages();
    sgd::AllocatorTuning::releaseFreeMemory();
    const long after = residentPages();
    std::free(pin);
    if (before < 0 || after < 0) return -1;
    return (before - after) * (sysconf(_SC_PAGESIZE) / 1024);
  });
}

}  // namespace

// Measured: untuned, the 9 passes fault 78,757 pages (all 34 MB every pass); tuned, none.
TEST(AllocatorTuning, FreedFrameBuffersAreReusedWithoutPageFaults) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer replaces the allocator (mallopt has no effect)";
#endif
  const long tuned = repeatedPassFaults(true);
  if (tuned == -1 && !sgd::AllocatorTuning::apply()) GTEST_SKIP() << "not glibc: mallopt unsupported";
  const long untuned = repeatedPassFaults(false);
  ASSERT_GE(tuned, 0);
  ASSERT_GE(untuned, 0);
  std::printf("page faults of 9 repeated passes: untuned %ld, tuned %ld\n", untuned, tuned);
  // 9 passes x 34 MB = 78,000 pages of 4 KiB; the tuned allocator keeps them mapped.
  EXPECT_GT(untuned, 40000);
  EXPECT_LT(tuned, 500);
}

// The free memory a tuned allocator keeps goes back to the kernel on request (the nodelet's
// ~release_memory_every_frames). Measured: 32,716 KiB of the 32,768 freed.
TEST(AllocatorTuning, ReleaseFreeMemoryReturnsFreedBlocksBelowTheHeapTop) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer replaces the allocator";
#endif
  const long kib = releasedKib();
  if (kib == -1 && !sgd::AllocatorTuning::releaseFreeMemory()) GTEST_SKIP() << "not glibc";
  std::printf("resident KiB returned: %ld\n", kib);
  EXPECT_GT(kib, 28 * 1024);
}

// ----------------------------------------------------------------------------------- NumberText
TEST(NumberText, ShortestRoundTripsAndParseIsStrict) {
  for (double v : {0.25, 0.1, -1.0 / 3.0, 1e-300, 6.02214076e23, -0.0, 123456789.125}) {
    double back = 0.0;
    ASSERT_TRUE(sgd::NumberText::parse(sgd::NumberText::shortest(v), &back)) << v;
    EXPECT_EQ(back, v);
  }
  EXPECT_EQ(sgd::NumberText::shortest(0.25), "0.25");
  EXPECT_EQ(sgd::NumberText::shortestFloat(0.1f), "0.1");
  EXPECT_EQ(sgd::NumberText::yaml(std::numeric_limits<double>::quiet_NaN()), ".nan");
  EXPECT_EQ(sgd::NumberText::yaml(-std::numeric_limits<double>::infinity()), "-.inf");
  double v = 0.0;
  EXPECT_FALSE(sgd::NumberText::parse("1.5x", &v));
  EXPECT_FALSE(sgd::NumberText::parse("", &v));
  EXPECT_FALSE(sgd::NumberText::parse("abc", &v));
  ASSERT_TRUE(sgd::NumberText::parse(".nan", &v));
  EXPECT_TRUE(std::isnan(v));
}

// -------------------------------------------------------------------------------------- GeoTiff
TEST_F(IoTest, GeoTiffRoundTripKeepsValuesNanAndGrid) {
  const sgd::GroundGrid grid = makeGrid(0.25, -7, 3, 5, 7);
  cv::Mat layer(grid.rows, grid.cols, CV_32FC1);
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) layer.at<float>(r, c) = 0.1f * r - 0.37f * c + 1e-3f * r * c;
  }
  layer.at<float>(0, 0) = kNan;
  layer.at<float>(2, 5) = kNan;
  layer.at<float>(4, 6) = -1234.5678f;
  const std::string file = path("dem.tif");
  sgd::GeoTiff::write(file, layer, grid);
  ASSERT_TRUE(fs::exists(file));
  EXPECT_FALSE(fs::exists(file + ".aux.xml")) << "everything must live inside the TIFF";

  sgd::GroundGrid back_grid;
  const cv::Mat back = sgd::GeoTiff::read(file, &back_grid);
  EXPECT_TRUE(back_grid.sameLayout(grid)) << back_grid.resolution_m << " " << back_grid.row0 << " "
                                          << back_grid.col0 << " " << back_grid.rows << " " << back_grid.cols;
  EXPECT_DOUBLE_EQ(back_grid.x0(), 0.75);
  EXPECT_DOUBLE_EQ(back_grid.y0(), -1.75);
  ASSERT_EQ(back.type(), CV_32FC1);
  ASSERT_EQ(back.rows, grid.rows);
  ASSERT_EQ(back.cols, grid.cols);
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const float a = layer.at<float>(r, c), b = back.at<float>(r, c);
      if (std::isnan(a)) {
        EXPECT_TRUE(std::isnan(b)) << r << "," << c;
      } else {
        EXPECT_EQ(a, b) << r << "," << c;
      }
    }
  }
  // TIFF row r is grid row r (south-up raster): the distinctive value stays at (4, 6).
  EXPECT_EQ(back.at<float>(4, 6), -1234.5678f);

  // Compressed: a constant 300 x 200 layer (240 kB of floats) takes a few kB.
  const std::string flat = path("flat.tif");
  sgd::GeoTiff::write(flat, cv::Mat(200, 300, CV_32FC1, cv::Scalar(0.5f)), makeGrid(0.5, 0, 0, 200, 300));
  EXPECT_LT(fs::file_size(flat), 20000u);
}

// Overwriting a GeoTIFF leaves the other files of its folder alone. GDAL's Create() deletes an
// existing dataset with its "sidecar" files, and its metadata readers count summary.txt (ALOS)
// among them: dem_offline's summary.txt vanished on every run into a used folder.
TEST_F(IoTest, GeoTiffOverwriteKeepsNeighbouringFiles) {
  const sgd::GroundGrid grid = makeGrid(0.5, 0, 0, 3, 4);
  const std::string file = path("dem.tif");
  sgd::GeoTiff::write(file, cv::Mat(grid.rows, grid.cols, CV_32FC1, cv::Scalar(1.0f)), grid);
  for (const char* name : {"summary.txt", "dem.yaml", "frames.csv", "dem.IMD", "dem.RPB", "dem_height.png"}) {
    spit(path(name), "keep me\n");
  }
  sgd::GeoTiff::write(file, cv::Mat(grid.rows, grid.cols, CV_32FC1, cv::Scalar(2.0f)), grid);
  for (const char* name : {"summary.txt", "dem.yaml", "frames.csv", "dem.IMD", "dem.RPB", "dem_height.png"}) {
    EXPECT_EQ(slurp(path(name)), "keep me\n") << name;
  }
  EXPECT_EQ(sgd::GeoTiff::read(file).at<float>(1, 1), 2.0f) << "the file itself is replaced";
}

TEST_F(IoTest, GeoTiffMultiBandKeepsNamesAndOrder) {
  const sgd::GroundGrid grid = makeGrid(0.5, 2, -4, 3, 4);
  const cv::Mat a(grid.rows, grid.cols, CV_32FC1, cv::Scalar(1.5f));
  const cv::Mat b(grid.rows, grid.cols, CV_32FC1, cv::Scalar(-2.0f));
  const std::string file = path("layers.tif");
  sgd::GeoTiff::writeLayers(file, {"elevation", "variance"}, {a, b}, grid);
  std::vector<std::string> names;
  sgd::GroundGrid back_grid;
  const std::vector<cv::Mat> back = sgd::GeoTiff::readLayers(file, &back_grid, &names);
  ASSERT_EQ(back.size(), 2u);
  ASSERT_EQ(names.size(), 2u);
  EXPECT_EQ(names[0], "elevation");
  EXPECT_EQ(names[1], "variance");
  EXPECT_EQ(back[0].at<float>(2, 3), 1.5f);
  EXPECT_EQ(back[1].at<float>(1, 1), -2.0f);
  EXPECT_TRUE(back_grid.sameLayout(grid));
}

TEST_F(IoTest, GeoTiffReadErrorsNameThePath) {
  const std::string missing = path("missing.tif");
  const std::string m1 = thrownMessage([&] { sgd::GeoTiff::read(missing); });
  EXPECT_NE(m1.find(missing), std::string::npos) << m1;
  EXPECT_NE(m1.find("no such file"), std::string::npos) << m1;

  const std::string text = path("not_a_tiff.tif");
  spit(text, "resolution: 0.5\nthis is not a TIFF\n");
  const std::string m2 = thrownMessage([&] { sgd::GeoTiff::read(text); });
  EXPECT_NE(m2.find(text), std::string::npos) << m2;
  EXPECT_EQ(m2.find('\n'), std::string::npos) << "one line: " << m2;

  // An ordinary picture is not a GeoTIFF either (GDAL could open it with another driver).
  const std::string png = path("picture.png");
  ASSERT_TRUE(cv::imwrite(png, cv::Mat(4, 4, CV_8UC1, cv::Scalar(7))));
  EXPECT_THROW(sgd::GeoTiff::read(png), std::runtime_error);
}

TEST_F(IoTest, GeoTiffWriteRejectsBadInput) {
  const sgd::GroundGrid grid = makeGrid(0.5, 0, 0, 3, 4);
  const std::string file = path("bad.tif");
  EXPECT_THROW(sgd::GeoTiff::write(file, cv::Mat(4, 3, CV_32FC1, cv::Scalar(0)), grid), std::runtime_error);
  EXPECT_THROW(sgd::GeoTiff::write(file, cv::Mat(3, 4, CV_64FC1, cv::Scalar(0)), grid), std::runtime_error);
  const std::string m = thrownMessage(
      [&] { sgd::GeoTiff::write(path("no_dir/x.tif"), cv::Mat(3, 4, CV_32FC1, cv::Scalar(0)), grid); });
  EXPECT_NE(m.find("no_dir/x.tif"), std::string::npos) << m;
}

// ---------------------------------------------------------------------------------- DemMetadata
TEST_F(IoTest, DemYamlRoundTripAndPlainYamlText) {
  const sgd::GroundGrid grid = makeGrid(0.25, -7, 3, 5, 7);
  const Eigen::Isometry3d pose = somePose(0.1, -0.05, -1.6, Eigen::Vector3d(0.1, -0.2, 1.65));
  sgd::DemMetadata m = sgd::DemMetadata::fromGrid(grid, pose, {"elevation", "variance"});
  m.extra_strings["sequence"] = "kitti 06: frames 0-50, \"quoted\" \\ back";
  m.extra_strings["five"] = "5";
  m.extra_numbers["frames"] = 51;
  m.extra_numbers["median_error_m"] = 0.0123456789;
  m.extra_numbers["unknown_value"] = std::numeric_limits<double>::quiet_NaN();
  const std::string file = path("dem.yaml");
  m.write(file);

  // The text a plain YAML parser sees.
  const std::vector<std::string> l = lines(slurp(file));
  const auto has_line_starting = [&l](const std::string& prefix) {
    for (const auto& s : l) {
      if (s.rfind(prefix, 0) == 0) return true;
    }
    return false;
  };
  EXPECT_TRUE(has_line_starting("resolution: 0.25")) << slurp(file);
  EXPECT_TRUE(has_line_starting("origin: [0.75, -1.75]")) << slurp(file);
  EXPECT_TRUE(has_line_starting("rows: 5"));
  EXPECT_TRUE(has_line_starting("cols: 7"));
  EXPECT_TRUE(has_line_starting("ground_T_camera0: ["));
  EXPECT_TRUE(has_line_starting("layers: [\"elevation\", \"variance\"]"));
  EXPECT_TRUE(
      has_line_starting("conventions: \"vertex (r,c) at x = x0 + c*resolution, y = y0 + r*resolution"));
  EXPECT_TRUE(has_line_starting("frames: 51"));
  EXPECT_TRUE(has_line_starting("five: \"5\""));
  EXPECT_TRUE(has_line_starting("unknown_value: .nan"));
  for (const auto& s : l) EXPECT_NE(s.rfind("%YAML", 0), 0u) << "no OpenCV-only header";

  const sgd::DemMetadata back = sgd::DemMetadata::read(file);
  EXPECT_EQ(back.resolution_m, 0.25);
  EXPECT_EQ(back.origin_x_m, 0.75);
  EXPECT_EQ(back.origin_y_m, -1.75);
  EXPECT_EQ(back.rows, 5);
  EXPECT_EQ(back.cols, 7);
  EXPECT_TRUE(back.ground_T_camera0.matrix() == pose.matrix()) << back.ground_T_camera0.matrix();
  EXPECT_EQ(back.layers, m.layers);
  EXPECT_EQ(back.conventions, sgd::DemMetadata::kConventions);
  EXPECT_EQ(back.extra_strings, m.extra_strings);
  ASSERT_EQ(back.extra_numbers.size(), 3u);
  EXPECT_EQ(back.extra_numbers.at("frames"), 51.0);
  EXPECT_EQ(back.extra_numbers.at("median_error_m"), 0.0123456789);
  EXPECT_TRUE(std::isnan(back.extra_numbers.at("unknown_value")));
  EXPECT_TRUE(back.grid().sameLayout(grid));
}

TEST_F(IoTest, DemYamlReadsHandWrittenPlainYaml) {
  // As written by python's yaml.safe_dump or by hand: document marker, comments, other spacing.
  const std::string file = path("hand.yaml");
  spit(file,
       "---\n# comment\nresolution: 0.5\norigin: [-1.0, 2.5]\nrows: 3\ncols: 4\n"
       "ground_T_camera0: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1.5, 0, 0, 0, 1]\n"
       "layers: [elevation]\nnote: hello world\n");
  const sgd::DemMetadata m = sgd::DemMetadata::read(file);
  EXPECT_EQ(m.resolution_m, 0.5);
  EXPECT_EQ(m.origin_x_m, -1.0);
  EXPECT_EQ(m.origin_y_m, 2.5);
  EXPECT_EQ(m.ground_T_camera0.translation().z(), 1.5);
  ASSERT_EQ(m.layers.size(), 1u);
  EXPECT_EQ(m.layers[0], "elevation");
  EXPECT_EQ(m.extra_strings.at("note"), "hello world");
  const sgd::GroundGrid g = m.grid();
  EXPECT_EQ(g.col0, -2);
  EXPECT_EQ(g.row0, 5);
}

TEST_F(IoTest, DemYamlErrors) {
  const std::string file = path("dem.yaml");
  sgd::DemMetadata m =
      sgd::DemMetadata::fromGrid(makeGrid(0.5, 0, 0, 2, 2), Eigen::Isometry3d::Identity(), {});
  m.extra_strings["rows"] = "clash";
  EXPECT_THROW(m.write(file), std::runtime_error);
  m.extra_strings.clear();
  m.extra_numbers["bad key"] = 1.0;
  EXPECT_THROW(m.write(file), std::runtime_error);

  spit(file, "origin: [0, 0]\nrows: 2\ncols: 2\n");
  const std::string msg = thrownMessage([&] { sgd::DemMetadata::read(file); });
  EXPECT_NE(msg.find(file), std::string::npos) << msg;
  EXPECT_NE(msg.find("resolution"), std::string::npos) << msg;
  EXPECT_THROW(sgd::DemMetadata::read(path("missing.yaml")), std::runtime_error);
  spit(file, "resolution: [unclosed\n");
  EXPECT_THROW(sgd::DemMetadata::read(file), std::runtime_error);
}

// --------------------------------------------------------------------------------- DisparityPng
TEST_F(IoTest, DisparityPngRoundTripWithinQuantisation) {
  cv::Mat d(6, 9, CV_32FC1);
  cv::RNG rng(42);
  rng.fill(d, cv::RNG::UNIFORM, 0.01, 200.0);
  d.at<float>(0, 0) = kNan;
  d.at<float>(0, 1) = -3.0f;
  d.at<float>(0, 2) = 0.0f;
  d.at<float>(0, 3) = std::numeric_limits<float>::infinity();
  d.at<float>(0, 4) = 300.0f;  // beyond 65535 / 256: clamped
  d.at<float>(0, 5) = 0.001f;  // rounds to 0 but stays valid: smallest code
  d.at<float>(0, 6) = 12.3456f;
  const std::string file = path("disp.png");
  sgd::DisparityPng::write(file, d);

  const cv::Mat raw = cv::imread(file, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  for (int c = 0; c < 4; ++c) EXPECT_EQ(raw.at<uint16_t>(0, c), 0) << c;
  EXPECT_EQ(raw.at<uint16_t>(0, 4), 65535);
  EXPECT_EQ(raw.at<uint16_t>(0, 5), 1);
  EXPECT_EQ(raw.at<uint16_t>(0, 6), static_cast<uint16_t>(std::lround(12.3456 * 256)));

  const cv::Mat back = sgd::DisparityPng::read(file);
  ASSERT_EQ(back.type(), CV_32FC1);
  for (int c = 0; c < 4; ++c) EXPECT_TRUE(std::isnan(back.at<float>(0, c))) << c;
  for (int r = 1; r < d.rows; ++r) {
    for (int c = 0; c < d.cols; ++c)
      EXPECT_LE(std::abs(back.at<float>(r, c) - d.at<float>(r, c)), 1.0 / 512 + 1e-6);
  }
  const cv::Mat zeros = sgd::DisparityPng::read(file, 0.0f);
  EXPECT_EQ(zeros.at<float>(0, 0), 0.0f);
  EXPECT_EQ(zeros.at<float>(0, 2), 0.0f);
  EXPECT_NEAR(zeros.at<float>(0, 6), 12.3456f, 1.0 / 512);
}

TEST_F(IoTest, DisparityPngRejectsEightBitAndMissing) {
  const std::string file = path("eight.png");
  ASSERT_TRUE(cv::imwrite(file, cv::Mat(3, 3, CV_8UC1, cv::Scalar(9))));
  const std::string msg = thrownMessage([&] { sgd::DisparityPng::read(file); });
  EXPECT_NE(msg.find(file), std::string::npos) << msg;
  EXPECT_NE(msg.find("16-bit"), std::string::npos) << msg;
  EXPECT_THROW(sgd::DisparityPng::read(path("none.png")), std::runtime_error);
}

// ----------------------------------------------------------------------------------- DemPicture
namespace {

/// Centroid of the map pixels that are clearly yellow (top of viridis), or (-1, -1).
cv::Point2d yellowCentroid(const cv::Mat& pic, const cv::Rect& map) {
  double sx = 0, sy = 0;
  int n = 0;
  for (int y = map.y; y < map.br().y; ++y) {
    for (int x = map.x; x < map.br().x; ++x) {
      const cv::Vec3b p = pic.at<cv::Vec3b>(y, x);
      if (p[2] > 200 && p[1] > 180 && p[0] < 100) {
        sx += x;
        sy += y;
        ++n;
      }
    }
  }
  return n > 0 ? cv::Point2d(sx / n, sy / n) : cv::Point2d(-1, -1);
}

}  // namespace

TEST(DemPicture, HighCellAtLargeXIsNearTheTop) {
  // 21 rows (y) x 41 cols (x); a bump at the far end (large x), centred in y.
  const sgd::GroundGrid grid = makeGrid(0.5, -10, 0, 21, 41);
  cv::Mat h(grid.rows, grid.cols, CV_32FC1, cv::Scalar(0.0f));
  h.at<float>(10, 38) = 2.0f;
  sgd::DemPictureLayout layout;
  const cv::Mat pic = sgd::DemPicture::heightPicture(h, grid, {}, {}, &layout);
  ASSERT_EQ(pic.type(), CV_8UC3);
  // x runs up the picture: the map is taller (41 cells) than wide (21 cells).
  EXPECT_GT(layout.map_rect.height, layout.map_rect.width);
  EXPECT_GE(std::max(pic.rows, pic.cols), 600);
  EXPECT_LE(std::max(pic.rows, pic.cols), 1500);
  const cv::Point2d yc = yellowCentroid(pic, layout.map_rect);
  ASSERT_GE(yc.x, 0.0) << "the high cell is not drawn in the top colour";
  EXPECT_LT(yc.y, layout.map_rect.y + 0.15 * layout.map_rect.height);
  EXPECT_NEAR(yc.x, layout.map_rect.x + 0.5 * layout.map_rect.width, 0.05 * layout.map_rect.width);
  const cv::Point2d expected = layout.pixelOf(grid.xOfCol(38), grid.yOfRow(10));
  EXPECT_NEAR(yc.x, expected.x, layout.pixels_per_cell);
  EXPECT_NEAR(yc.y, expected.y, layout.pixels_per_cell);
}

TEST(DemPicture, HighCellAtLargeYIsOnTheLeft) {
  const sgd::GroundGrid grid = makeGrid(0.5, -10, 0, 21, 41);
  cv::Mat h(grid.rows, grid.cols, CV_32FC1, cv::Scalar(0.0f));
  h.at<float>(19, 20) = 2.0f;  // large y (left of the vehicle), middle of x
  sgd::DemPictureLayout layout;
  const cv::Mat pic = sgd::DemPicture::heightPicture(h, grid, {}, {}, &layout);
  const cv::Point2d yc = yellowCentroid(pic, layout.map_rect);
  ASSERT_GE(yc.x, 0.0);
  EXPECT_LT(yc.x, layout.map_rect.x + 0.15 * layout.map_rect.width);
  EXPECT_NEAR(yc.y, layout.map_rect.y + 0.5 * layout.map_rect.height, 0.05 * layout.map_rect.height);
}

TEST(DemPicture, UnknownCellsAreGreyAndTrajectoryStartIsMarked) {
  const sgd::GroundGrid grid = makeGrid(0.5, -10, 0, 21, 41);
  cv::Mat h(grid.rows, grid.cols, CV_32FC1);
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) h.at<float>(r, c) = 0.05f * c + 0.02f * r;  // a tilted plane
  }
  h.at<float>(3, 30) = kNan;
  sgd::DemPictureOptions o;
  o.pixels_per_cell = 12;
  sgd::DemPictureLayout layout;
  const std::vector<Eigen::Vector2d> traj = {{2.0, 0.0}, {6.0, 0.5}, {12.0, 1.0}};
  const cv::Mat pic = sgd::DemPicture::heightPicture(h, grid, o, traj, &layout);
  EXPECT_EQ(layout.pixels_per_cell, 12.0);
  EXPECT_EQ(layout.map_rect.width, 21 * 12);
  EXPECT_EQ(layout.map_rect.height, 41 * 12);
  const cv::Point2d unknown = layout.pixelOf(grid.xOfCol(30), grid.yOfRow(3));
  EXPECT_EQ(pic.at<cv::Vec3b>(cv::Point(unknown)), o.unknown_bgr);
  // A known cell is coloured, not grey.
  const cv::Point2d known = layout.pixelOf(grid.xOfCol(30), grid.yOfRow(5));
  EXPECT_NE(pic.at<cv::Vec3b>(cv::Point(known)), o.unknown_bgr);
  // The start marker (green disc) is at the first trajectory point.
  const cv::Vec3b start = pic.at<cv::Vec3b>(cv::Point(layout.pixelOf(2.0, 0.0)));
  EXPECT_GT(start[1], 150);
  EXPECT_LT(start[0], 100);
  EXPECT_LT(start[2], 100);
}

TEST(DemPicture, HillShadingLightsSlopesFacingNorthWest) {
  // Two planes with the same height at the centre vertex: one falls towards +x and +y (faces the
  // light from the north-west = forward-left), the other rises.
  const sgd::GroundGrid grid = makeGrid(0.5, -5, 0, 11, 11);
  cv::Mat facing(grid.rows, grid.cols, CV_32FC1), away(grid.rows, grid.cols, CV_32FC1);
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      facing.at<float>(r, c) = -0.3f * (c - 5) - 0.3f * (r - 5);
      away.at<float>(r, c) = 0.3f * (c - 5) + 0.3f * (r - 5);
    }
  }
  sgd::DemPictureOptions o;
  o.min_value = -5.0;
  o.max_value = 5.0;
  const auto centre_brightness = [&](const cv::Mat& h, const sgd::DemPictureOptions& opt) {
    sgd::DemPictureLayout layout;
    const cv::Mat pic = sgd::DemPicture::heightPicture(h, grid, opt, {}, &layout);
    const cv::Vec3b p = pic.at<cv::Vec3b>(cv::Point(layout.pixelOf(grid.xOfCol(5), grid.yOfRow(5))));
    return p[0] + p[1] + p[2];
  };
  EXPECT_GT(centre_brightness(facing, o), centre_brightness(away, o) + 60);
  o.hillshade = false;
  EXPECT_EQ(centre_brightness(facing, o), centre_brightness(away, o));
}

TEST(DemPicture, TraversabilityColours) {
  const sgd::GroundGrid grid = makeGrid(0.5, 0, 0, 10, 10);
  cv::Mat t(grid.rows, grid.cols, CV_32FC1, cv::Scalar(1.0f));
  t.at<float>(2, 2) = 0.0f;
  t.at<float>(5, 5) = kNan;
  sgd::DemPictureLayout layout;
  const cv::Mat pic = sgd::DemPicture::traversabilityPicture(t, grid, {}, {}, &layout);
  const cv::Vec3b blocked = pic.at<cv::Vec3b>(cv::Point(layout.pixelOf(1.0, 1.0)));
  const cv::Vec3b free_cell = pic.at<cv::Vec3b>(cv::Point(layout.pixelOf(4.0, 1.0)));
  const cv::Vec3b unknown = pic.at<cv::Vec3b>(cv::Point(layout.pixelOf(2.5, 2.5)));
  EXPECT_GT(blocked[2], 180);  // red
  EXPECT_LT(blocked[1], 80);
  EXPECT_GT(free_cell[1], 150);  // green
  EXPECT_LT(free_cell[2], 80);
  EXPECT_EQ(unknown, sgd::DemPictureOptions().unknown_bgr);
}

TEST(DemPicture, OverlayColoursOnlyPixelsWithValues) {
  const cv::Mat image(40, 600, CV_8UC1, cv::Scalar(128));
  cv::Mat values(40, 600, CV_32FC1, cv::Scalar(0.0f));
  values(cv::Rect(100, 10, 50, 20)).setTo(30.0f);
  values(cv::Rect(300, 10, 50, 20)).setTo(kNan);
  values.at<float>(5, 5) = 10.0f;
  const cv::Mat pic = sgd::DemPicture::overlayOnImage(image, values, 0.0, 40.0, "disparity [px]");
  ASSERT_EQ(pic.type(), CV_8UC3);
  EXPECT_EQ(pic.cols, 600);
  EXPECT_GT(pic.rows, 40);                                          // legend strip below
  EXPECT_EQ(pic.at<cv::Vec3b>(20, 320), cv::Vec3b(128, 128, 128));  // NaN: untouched
  EXPECT_EQ(pic.at<cv::Vec3b>(35, 500), cv::Vec3b(128, 128, 128));  // 0: untouched
  const cv::Vec3b hi = pic.at<cv::Vec3b>(20, 120);
  const cv::Vec3b lo = pic.at<cv::Vec3b>(5, 5);
  EXPECT_NE(hi, cv::Vec3b(128, 128, 128));
  EXPECT_NE(hi, lo);  // different values, different colours
  EXPECT_THROW(sgd::DemPicture::overlayOnImage(image, cv::Mat(10, 10, CV_32FC1), 0, 1, "x"),
               std::invalid_argument);
}

TEST(DemPicture, OverlayTakesEveryCameraImageType) {
  cv::Mat values(40, 600, CV_32FC1, cv::Scalar(0.0f));
  values(cv::Rect(100, 10, 50, 20)).setTo(30.0f);
  const cv::Mat bgra(40, 600, CV_8UC4, cv::Scalar(128, 128, 128, 3));
  const cv::Mat g12(40, 600, CV_16UC1, cv::Scalar(2056));  // 12-bit: 2056 * 255 / 4095 = 128
  const cv::Mat f(40, 600, CV_32FC1, cv::Scalar(128.0f));
  const cv::Mat c16(40, 600, CV_16UC3, cv::Scalar(2056, 2056, 2056));
  for (const cv::Mat& image : {bgra, g12, f, c16}) {
    const cv::Mat pic = sgd::DemPicture::overlayOnImage(image, values, 0.0, 40.0, "disparity [px]");
    ASSERT_EQ(pic.type(), CV_8UC3);
    EXPECT_EQ(pic.at<cv::Vec3b>(35, 500), cv::Vec3b(128, 128, 128)) << sgd::GreyConverter::typeName(image.type());
  }
  // a 16-bit image with its bit depth given: 2056 of 16 bits is dark
  sgd::DemPictureOptions o;
  o.image_bit_depth = 16;
  EXPECT_EQ(sgd::DemPicture::overlayOnImage(g12, values, 0.0, 40.0, "d", o).at<cv::Vec3b>(35, 500), cv::Vec3b(8, 8, 8));
  try {
    sgd::DemPicture::overlayOnImage(cv::Mat(40, 600, CV_8UC2), values, 0.0, 40.0, "d");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "DemPicture::overlayOnImage: unsupported image type CV_8UC2 (accepted: CV_8UC1/3/4, "
                           "CV_16UC1/3/4, CV_32FC1)");
  }
}

TEST(DemPicture, RobustRangeIgnoresOutliersAndNan) {
  cv::Mat l(1, 100, CV_32FC1);
  for (int i = 0; i < 100; ++i) l.at<float>(0, i) = static_cast<float>(i);
  l.at<float>(0, 0) = -1e6f;
  l.at<float>(0, 99) = 1e6f;
  l.at<float>(0, 50) = kNan;
  double lo = 0, hi = 0;
  ASSERT_TRUE(sgd::DemPicture::robustRange(l, 2, 98, &lo, &hi));
  EXPECT_GT(lo, 0.0);
  EXPECT_LT(lo, 5.0);
  EXPECT_GT(hi, 94.0);
  EXPECT_LT(hi, 99.0);
  EXPECT_FALSE(sgd::DemPicture::robustRange(cv::Mat(2, 2, CV_32FC1, cv::Scalar(kNan)), 2, 98, &lo, &hi));
}

// ------------------------------------------------------------------------------------ PlyWriter
namespace {

struct PlyHeader {
  std::string format;
  int vertices = -1;
  int faces = -1;
  size_t body_offset = 0;
};

PlyHeader parsePlyHeader(const std::string& text) {
  PlyHeader h;
  std::istringstream is(text);
  std::string line;
  while (std::getline(is, line)) {
    std::istringstream ls(line);
    std::string a, b;
    ls >> a >> b;
    if (a == "format") h.format = b;
    if (a == "element" && b == "vertex") ls >> h.vertices;
    if (a == "element" && b == "face") ls >> h.faces;
    if (a == "end_header") {
      h.body_offset = static_cast<size_t>(is.tellg());
      break;
    }
  }
  return h;
}

}  // namespace

TEST_F(IoTest, PlyFaceCountWithHoles) {
  const sgd::GroundGrid grid = makeGrid(0.5, -2, 4, 4, 5);  // 3 x 4 squares = 24 triangles
  cv::Mat h(grid.rows, grid.cols, CV_32FC1, cv::Scalar(0.25f));
  h.at<float>(1, 2) = kNan;  // interior vertex: in 6 triangles
  h.at<float>(0, 0) = kNan;  // corner on the diagonal: in 2 triangles
  h.at<float>(3, 0) = kNan;  // corner off the diagonal: in 1 triangle
  const int expected_faces = 24 - 6 - 2 - 1;
  const int expected_vertices = 20 - 3;

  const std::string ascii = path("mesh_ascii.ply");
  const sgd::PlyMeshStats s = sgd::PlyWriter::writeMesh(ascii, grid, h, true, sgd::PlyFormat::kAscii);
  EXPECT_EQ(s.faces, expected_faces);
  EXPECT_EQ(s.vertices, expected_vertices);
  const std::string text = slurp(ascii);
  const PlyHeader ha = parsePlyHeader(text);
  EXPECT_EQ(ha.format, "ascii");
  EXPECT_EQ(ha.vertices, expected_vertices);
  EXPECT_EQ(ha.faces, expected_faces);
  const std::vector<std::string> body = lines(text.substr(ha.body_offset));
  ASSERT_EQ(body.size(), static_cast<size_t>(expected_vertices + expected_faces));
  // First vertex: (r 0, c 1) at x = (4 + 1) * 0.5, y = -2 * 0.5.
  std::istringstream v0(body[0]);
  double x = 0, y = 0, z = 0;
  v0 >> x >> y >> z;
  EXPECT_DOUBLE_EQ(x, 2.5);
  EXPECT_DOUBLE_EQ(y, -1.0);
  EXPECT_DOUBLE_EQ(z, 0.25);
  std::vector<Eigen::Vector2d> xy;
  for (int v = 0; v < expected_vertices; ++v) {
    std::istringstream vs(body[static_cast<size_t>(v)]);
    double px = 0, py = 0;
    vs >> px >> py;
    xy.emplace_back(px, py);
  }
  for (int f = 0; f < expected_faces; ++f) {
    std::istringstream fs_(body[static_cast<size_t>(expected_vertices + f)]);
    int n = 0, a = -1, b = -1, c = -1;
    fs_ >> n >> a >> b >> c;
    EXPECT_EQ(n, 3);
    bool in_range = true;
    for (int i : {a, b, c}) in_range = in_range && i >= 0 && i < expected_vertices;
    ASSERT_TRUE(in_range) << body[static_cast<size_t>(expected_vertices + f)];
    const Eigen::Vector2d e1 = xy[static_cast<size_t>(b)] - xy[static_cast<size_t>(a)];
    const Eigen::Vector2d e2 = xy[static_cast<size_t>(c)] - xy[static_cast<size_t>(a)];
    EXPECT_GT(e1.x() * e2.y() - e1.y() * e2.x(), 0.0) << "face " << f << " is not counter-clockwise from +z";
  }

  const std::string bin = path("mesh_bin.ply");
  sgd::PlyWriter::writeMesh(bin, grid, h, true, sgd::PlyFormat::kBinaryLittleEndian);
  const std::string data = slurp(bin);
  const PlyHeader hb = parsePlyHeader(data);
  EXPECT_EQ(hb.format, "binary_little_endian");
  EXPECT_EQ(hb.faces, expected_faces);
  // 3 floats + 3 bytes per vertex, 1 byte + 3 ints per face.
  EXPECT_EQ(data.size(), hb.body_offset + static_cast<size_t>(expected_vertices) * 15 +
                             static_cast<size_t>(expected_faces) * 13);
}

// ------------------------------------------------------------------------------ Trajectories
TEST_F(IoTest, KittiTrajectoryRoundTripIsExact) {
  std::vector<Eigen::Isometry3d> poses;
  for (int k = 0; k < 5; ++k)
    poses.push_back(somePose(0.01 * k, -0.02 * k, 0.003 * k, Eigen::Vector3d(0.1 * k, -0.01, 0.8 * k)));
  const std::string file = path("poses.txt");
  sgd::TrajectoryWriter::writeKitti(file, poses);
  const std::vector<std::string> l = lines(slurp(file));
  ASSERT_EQ(l.size(), 5u);
  EXPECT_EQ(l[0], "1 0 0 0 0 1 0 -0.01 0 0 1 0");
  const std::vector<Eigen::Isometry3d> back = sgd::TrajectoryWriter::readKitti(file);
  ASSERT_EQ(back.size(), poses.size());
  for (size_t k = 0; k < poses.size(); ++k) EXPECT_TRUE(back[k].matrix() == poses[k].matrix()) << k;
}

TEST_F(IoTest, TumTrajectoryRoundTrip) {
  std::vector<Eigen::Isometry3d> poses;
  std::vector<double> stamps;
  for (int k = 0; k < 4; ++k) {
    poses.push_back(somePose(0.3 * k, -0.1 * k, 0.2, Eigen::Vector3d(1.0 * k, 2.0, -0.5 * k)));
    stamps.push_back(1317384506.123456 + 0.1 * k);
  }
  const std::string file = path("traj.tum");
  sgd::TrajectoryWriter::writeTum(file, stamps, poses);
  const sgd::StampedTrajectory back = sgd::TrajectoryWriter::readTum(file);
  ASSERT_EQ(back.poses.size(), 4u);
  ASSERT_EQ(back.stamps_s.size(), 4u);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(back.stamps_s[k], stamps[k]);
    EXPECT_LT((back.poses[k].matrix() - poses[k].matrix()).cwiseAbs().maxCoeff(), 1e-12) << k;
  }
  // Field order: t tx ty tz qx qy qz qw.
  std::istringstream first(lines(slurp(file))[1]);
  std::vector<double> v(8);
  for (double& x : v) first >> x;
  EXPECT_EQ(v[1], 0.0);
  EXPECT_EQ(v[2], 2.0);
  const Eigen::Quaterniond q(poses[0].rotation());
  EXPECT_NEAR(std::abs(v[7]), std::abs(q.w()), 1e-12);
  EXPECT_THROW(sgd::TrajectoryWriter::writeTum(file, {1.0}, poses), std::runtime_error);
}

TEST_F(IoTest, MalformedTrajectoryLinesThrowWithLineNumber) {
  const std::string kitti = path("bad_kitti.txt");
  spit(kitti, "1 0 0 0 0 1 0 0 0 0 1 0\n\n1 0 0 1 0 1 0 2 0 0 1\n");
  std::string msg = thrownMessage([&] { sgd::TrajectoryWriter::readKitti(kitti); });
  EXPECT_NE(msg.find(kitti + ":3:"), std::string::npos) << msg;

  spit(kitti, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 abc\n");
  msg = thrownMessage([&] { sgd::TrajectoryWriter::readKitti(kitti); });
  EXPECT_NE(msg.find(kitti + ":2:"), std::string::npos) << msg;

  spit(kitti, "2 0 0 0 0 1 0 0 0 0 1 0\n");  // not a rotation
  msg = thrownMessage([&] { sgd::TrajectoryWriter::readKitti(kitti); });
  EXPECT_NE(msg.find(kitti + ":1:"), std::string::npos) << msg;

  const std::string tum = path("bad.tum");
  spit(tum, "# header\n0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0\n");
  msg = thrownMessage([&] { sgd::TrajectoryWriter::readTum(tum); });
  EXPECT_NE(msg.find(tum + ":3:"), std::string::npos) << msg;

  spit(tum, "0.0 1 2 3 0 0 0 0\n");
  msg = thrownMessage([&] { sgd::TrajectoryWriter::readTum(tum); });
  EXPECT_NE(msg.find(tum + ":1:"), std::string::npos) << msg;

  EXPECT_THROW(sgd::TrajectoryWriter::readKitti(path("missing.txt")), std::runtime_error);
}

// ------------------------------------------------------------------------------- ImageFileReader

TEST_F(IoTest, ImageFileReaderNamesEveryProblem) {
  const cv::Mat image(50, 60, CV_16UC1, cv::Scalar(1000));
  ASSERT_TRUE(cv::imwrite(path("ok.png"), image));
  std::string why = "stale";
  const cv::Mat back = sgd::ImageFileReader::read(path("ok.png"), &why);
  EXPECT_EQ(back.type(), CV_16UC1);
  EXPECT_EQ(why, "");
  const std::string png = slurp(path("ok.png"));
  const auto problem = [&](const std::string& name, const std::string& bytes) {
    spit(path(name), bytes);
    std::string w;
    EXPECT_TRUE(sgd::ImageFileReader::read(path(name), &w).empty()) << name;
    return w;
  };
  EXPECT_EQ(problem("empty.png", ""), "cannot read image '" + path("empty.png") + "' (empty file)");
  EXPECT_EQ(problem("cut.png", png.substr(0, 40)),
            "cannot read image '" + path("cut.png") + "' (truncated PNG (ends inside a chunk header at byte 33))");
  EXPECT_EQ(problem("cut2.png", png.substr(0, 60)),
            "cannot read image '" + path("cut2.png") + "' (truncated PNG (chunk at byte 33 runs past the end of the file))");
  EXPECT_EQ(problem("noend.png", png.substr(0, png.size() - 12)),
            "cannot read image '" + path("noend.png") + "' (truncated PNG (ends inside a chunk header at byte " +
                std::to_string(png.size() - 12) + "))");
  std::string flipped = png;
  flipped[45] = static_cast<char>(flipped[45] ^ 1);
  EXPECT_EQ(problem("flip.png", flipped),
            "cannot read image '" + path("flip.png") + "' (corrupt PNG (CRC mismatch in the IDAT chunk at byte 33))");
  EXPECT_EQ(problem("text.png", "hello\n"), "cannot read image '" + path("text.png") + "' (not an image OpenCV can decode)");
  std::vector<uchar> jpg;
  cv::imencode(".jpg", cv::Mat(50, 60, CV_8UC1, cv::Scalar(9)), jpg);
  EXPECT_EQ(problem("cut.jpg", std::string(jpg.begin(), jpg.begin() + static_cast<long>(jpg.size() / 2))),
            "cannot read image '" + path("cut.jpg") + "' (truncated JPEG (no end-of-image marker))");
  EXPECT_TRUE(sgd::ImageFileReader::read(path("missing.png"), &why).empty());
  EXPECT_EQ(why, "cannot read image '" + path("missing.png") + "' (no such file)");
  fs::create_directories(path("dir.png"));
  sgd::ImageFileReader::read(path("dir.png"), &why);
  EXPECT_EQ(why, "cannot read image '" + path("dir.png") + "' (not a regular file)");
}

// ------------------------------------------------------------------------------- KittiSequence layouts

TEST_F(IoTest, KittiSequenceChoosesTheCameraPair) {
  // KITTI raw layout: image_00/data .. image_03/data and calib_cam_to_cam.txt with all four cameras
  const cv::Mat grey(60, 80, CV_8UC1, cv::Scalar(90)), colour(60, 80, CV_8UC3, cv::Scalar(90, 90, 90));
  for (int cam = 0; cam < 4; ++cam) {
    const std::string d = path("raw/image_0" + std::to_string(cam) + "/data");
    fs::create_directories(d);
    for (int f = 0; f < 2; ++f) cv::imwrite(d + "/000000000" + std::to_string(f) + ".png", cam < 2 ? grey : colour);
  }
  spit(path("raw/calib_cam_to_cam.txt"),
       "S_rect_00: 80 60\nP_rect_00: 50 0 40 0 0 50 30 0 0 0 1 0\nP_rect_01: 50 0 40 -27 0 50 30 0 0 0 1 0\n"
       "S_rect_02: 80 60\nP_rect_02: 50 0 40 2 0 50 30 0.1 0 0 1 0\nP_rect_03: 50 0 40 -25 0 50 30 0.2 0 0 1 0\n");
  const sgd::KittiSequence automatic = sgd::KittiSequence::open(path("raw"));
  EXPECT_EQ(automatic.cameras(), sgd::CalibrationReader::CameraPair::kGray);
  EXPECT_EQ(automatic.leftFolder(), path("raw/image_00/data"));
  EXPECT_NEAR(automatic.rig().baseline_m, 0.54, 1e-12);
  EXPECT_TRUE(automatic.warnings().empty());
  sgd::KittiSequenceOptions o;
  o.cameras = sgd::CalibrationReader::CameraPair::kColor;
  const sgd::KittiSequence colour_pair = sgd::KittiSequence::open(path("raw"), o);
  EXPECT_EQ(colour_pair.leftFolder(), path("raw/image_02/data"));
  EXPECT_NEAR(colour_pair.rig().baseline_m, 0.54, 1e-12);
  EXPECT_NEAR(colour_pair.rig().right_offset_y_m, -0.002, 1e-12);
  ASSERT_EQ(colour_pair.warnings().size(), 1u);
  EXPECT_EQ(colour_pair.warnings()[0].rfind("stereo calibration: the right camera is displaced by y -0.002 m", 0), 0u);
  EXPECT_EQ(colour_pair.size(), 2);
  cv::Mat l, r;
  colour_pair.read(1, &l, &r);
  EXPECT_EQ(l.type(), CV_8UC3);
  // without the grey folders the colour pair is the automatic choice
  fs::remove_all(path("raw/image_00"));
  EXPECT_EQ(sgd::KittiSequence::open(path("raw")).cameras(), sgd::CalibrationReader::CameraPair::kColor);
}

TEST_F(IoTest, KittiOdometryColourFoldersUseP2P3) {
  // a KITTI odometry calib.txt with all four cameras and only the colour folders image_2/image_3
  const cv::Mat colour(60, 80, CV_8UC3, cv::Scalar(90, 90, 90));
  for (const char* d : {"odo/image_2", "odo/image_3"}) {
    fs::create_directories(path(d));
    cv::imwrite(path(d) + "/000000.png", colour);
  }
  spit(path("odo/calib.txt"),
       "P0: 50 0 40 0 0 50 30 0 0 0 1 0\nP1: 50 0 40 -27 0 50 30 0 0 0 1 0\n"
       "P2: 50 0 40 2 0 50 30 0.1 0 0 1 0\nP3: 50 0 40 -24 0 50 30 0.2 0 0 1 0\nTr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  const sgd::KittiSequence s = sgd::KittiSequence::open(path("odo"));
  EXPECT_EQ(s.cameras(), sgd::CalibrationReader::CameraPair::kColor);
  EXPECT_NEAR(s.rig().baseline_m, 0.52, 1e-12);  // P2/P3, not P0/P1 (0.54)
  EXPECT_EQ(s.rig().width, 80);
  // a calib.txt with the grey pair only does not serve colour folders: an error, not P0/P1
  spit(path("odo/calib.txt"), "P0: 50 0 40 0 0 50 30 0 0 0 1 0\nP1: 50 0 40 -27 0 50 30 0 0 0 1 0\n");
  EXPECT_EQ(thrownMessage([&] { sgd::KittiSequence::open(path("odo")); }),
            "sequence '" + path("odo") + "': " + path("odo") +
                "/calib.txt has no calibration for the cameras of the image folders found (image_2/image_3)");
}

TEST(OrthoTexture, PictureIsDrawnForwardUpLeftLeft) {
  // Raster rows run along +y, columns along +x; the picture has +x up and +y to the left.
  cv::Mat r(3, 5, CV_32F, cv::Scalar(std::nan("")));
  r.at<float>(0, 4) = 200.0f;  // the most forward column, the rightmost row (smallest y)
  r.at<float>(2, 0) = 50.0f;   // the rearmost, leftmost
  const cv::Mat p = sgd::DemExporter::orthoPicture(r);
  ASSERT_EQ(p.type(), CV_8UC4);
  ASSERT_EQ(p.rows, 5);
  ASSERT_EQ(p.cols, 3);
  EXPECT_EQ(p.at<cv::Vec4b>(0, 2), cv::Vec4b(200, 200, 200, 255));  // top right
  EXPECT_EQ(p.at<cv::Vec4b>(4, 0), cv::Vec4b(50, 50, 50, 255));     // bottom left
  EXPECT_EQ(p.at<cv::Vec4b>(2, 1)[3], 0);                             // unknown: transparent
}

TEST_F(IoTest, OrthoLayersAreWrittenBesideTheDem) {
  sgd::DemExport dem;
  dem.grid = sgd::GroundGrid::covering(0.0, 2.0, -1.0, 1.0, 0.5);
  dem.elevation = cv::Mat(dem.grid.rows, dem.grid.cols, CV_32F, cv::Scalar(0.1f));
  dem.intensity = cv::Mat(dem.grid.rows, dem.grid.cols, CV_32F, cv::Scalar(90.0f));
  dem.ortho_grid = sgd::GroundGrid::covering(0.0, 2.0, -1.0, 1.0, 0.1);
  dem.ortho = cv::Mat(dem.ortho_grid.rows, dem.ortho_grid.cols, CV_32F, cv::Scalar(kNan));
  dem.ortho.at<float>(3, 7) = 123.5f;
  const std::vector<std::string> files = sgd::DemExporter::write(dir_.string(), dem);
  for (const char* f : {"intensity.tif", "ortho.tif", "ortho.png"})
    EXPECT_NE(std::find(files.begin(), files.end(), f), files.end()) << f;
  sgd::GroundGrid g;
  const cv::Mat o = sgd::GeoTiff::read(path("ortho.tif"), &g);
  EXPECT_TRUE(g.sameLayout(dem.ortho_grid));
  EXPECT_FLOAT_EQ(o.at<float>(3, 7), 123.5f);
  EXPECT_EQ(cv::countNonZero(o == o), 1);
  const cv::Mat png = cv::imread(path("ortho.png"), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(png.type(), CV_8UC4);
  EXPECT_EQ(png.rows, dem.ortho_grid.cols);
  EXPECT_EQ(png.at<cv::Vec4b>(dem.ortho_grid.cols - 1 - 7, dem.ortho_grid.rows - 1 - 3), cv::Vec4b(124, 124, 124, 255));
  EXPECT_FLOAT_EQ(sgd::GeoTiff::read(path("intensity.tif")).at<float>(0, 0), 90.0f);
  const sgd::DemMetadata meta = sgd::DemMetadata::read(path("dem.yaml"));
  EXPECT_EQ(meta.extra_strings.at("ortho_file"), "ortho.tif");
  EXPECT_EQ(meta.extra_strings.at("intensity_file"), "intensity.tif");
  EXPECT_DOUBLE_EQ(meta.extra_numbers.at("ortho_resolution"), 0.1);
}
