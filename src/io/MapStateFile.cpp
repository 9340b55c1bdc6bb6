#include "stereo_ground_dem/io/MapStateFile.hpp"

#include <filesystem>
#include <fstream>
#include <memory>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {

namespace fs = std::filesystem;
constexpr int kFormatVersion = 1;

cv::Mat toMat(const Eigen::MatrixXd& m) {
  cv::Mat out;
  cv::eigen2cv(m, out);
  return out;
}

void writeImage(const std::string& path, const cv::Mat& image) {
  if (image.empty()) return;
  bool ok = false;
  try {
    ok = cv::imwrite(path, image);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw std::runtime_error("cannot write '" + path + "'");
}

cv::Mat readImage(const std::string& path, int type) {
  if (!fs::exists(path)) return cv::Mat();
  const cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (m.empty() || m.type() != type) throw std::runtime_error("'" + path + "' is unreadable or of the wrong type");
  return m;
}

template <class Layer>
void writeRecord(const std::string& path, const Layer& layer) {
  std::ofstream out(path, std::ios::binary);
  layer.write(out);
  out.close();
  if (!out) throw std::runtime_error("cannot write '" + path + "'");
}

template <class Layer>
void readRecord(const std::string& path, Layer* layer, bool saved) {
  if (!layer || !saved) return;
  if (!fs::exists(path)) throw std::runtime_error("'" + path + "' is missing");
  std::ifstream in(path, std::ios::binary);
  try {
    layer->read(in);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("'" + path + "': " + e.what());
  }
}

/// A matrix node as CV_64F (whatever type the file declares: no read past a buffer).
cv::Mat readMatrix(const cv::FileNode& n) {
  cv::Mat m;
  n >> m;
  if (!m.empty() && m.type() != CV_64F) {
    if (m.channels() != 1) return cv::Mat();
    m.convertTo(m, CV_64F);
  }
  return m;
}

Eigen::Isometry3d readPose(const cv::FileNode& n, const std::string& name) {
  cv::Mat m = readMatrix(n);
  if (m.rows != 4 || m.cols != 4 || m.type() != CV_64F) throw std::runtime_error(name + " is not a 4x4 matrix");
  Eigen::Matrix4d e;
  cv::cv2eigen(m, e);
  Eigen::Isometry3d t;
  t.matrix() = e;
  return t;
}

}  // namespace

bool MapStateFile::exists(const std::string& directory) { return fs::exists(fs::path(directory) / "state.yaml"); }

void MapStateFile::write(const std::string& directory, const SavedMapState& state, const ElevationMap& map,
                         const OrthoTexture* ortho, const PhotometricResidualMap* residual) {
  const fs::path dir(directory);
  std::error_code ec;
  fs::create_directories(dir / "map", ec);
  if (ec) throw std::runtime_error("cannot create '" + (dir / "map").string() + "': " + ec.message());
  // a previous save here: its files must not mix with this one's, and while this one is written
  // the directory is not a saved state (state.yaml goes first and comes back last)
  fs::remove(dir / "state.yaml", ec);
  for (const auto& e : fs::directory_iterator(dir / "map")) {
    const std::string name = e.path().filename().string();
    if (name.rfind("tile_", 0) == 0) fs::remove(e.path(), ec);
  }
  for (const char* name : {"previous_left.tif", "previous_right.tif", "last_left.tif", "ortho.bin", "residual.bin"})
    fs::remove(dir / name, ec);
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().rfind("previous_obstacles_", 0) == 0 ||
        e.path().filename().string().rfind("previous_moving_", 0) == 0 ||
        e.path().filename().string().rfind("carried_moving_", 0) == 0)
      fs::remove(e.path(), ec);

  map.saveTiles((dir / "map").string());
  const EstimatorState& s = state.estimator;
  writeImage((dir / "previous_left.tif").string(), s.previous_left);
  writeImage((dir / "previous_right.tif").string(), s.previous_right);
  writeImage((dir / "last_left.tif").string(), s.last_left);
  for (size_t l = 0; l < s.previous_obstacles.size(); ++l)
    writeImage((dir / ("previous_obstacles_" + std::to_string(l) + ".png")).string(), s.previous_obstacles[l]);
  for (size_t l = 0; l < s.previous_moving.size(); ++l)
    writeImage((dir / ("previous_moving_" + std::to_string(l) + ".png")).string(), s.previous_moving[l]);
  for (size_t l = 0; l < s.carried_moving.size(); ++l)
    writeImage((dir / ("carried_moving_" + std::to_string(l) + ".png")).string(), s.carried_moving[l]);
  if (ortho) writeRecord((dir / "ortho.bin").string(), *ortho);
  if (residual) writeRecord((dir / "residual.bin").string(), *residual);

  // state.yaml last: a directory without it is not a saved state (exists())
  const std::string path = (dir / "state.yaml").string();
  cv::FileStorage fsw(path, cv::FileStorage::WRITE);
  if (!fsw.isOpened()) throw std::runtime_error("cannot write '" + path + "'");
  fsw << "format_version" << kFormatVersion;
  fsw << "sequence" << state.sequence << "next_sequence_frame" << state.next_sequence_frame;
  fsw << "image_width_px" << state.image_width_px << "image_height_px" << state.image_height_px;
  fsw << "map_resolution_m" << map.options().resolution_m << "map_tile_size" << map.options().tile_size;
  fsw << "map_tiles" << static_cast<int>(map.tileCount());
  fsw << "ortho_saved" << static_cast<int>(ortho != nullptr) << "residual_saved" << static_cast<int>(residual != nullptr);
  fsw << "initialized" << static_cast<int>(s.initialized) << "frame_counter" << s.frame_counter;
  fsw << "ground_T_camera0" << toMat(s.ground_T_camera0.matrix());
  fsw << "ground_T_camera" << toMat(s.ground_T_camera.matrix());
  fsw << "last_camera_T_ground" << toMat(s.last_camera_T_ground.matrix());
  fsw << "last_stamp_s" << s.last_stamp_s << "velocity" << toMat(s.velocity);
  fsw << "velocity_gap_s" << s.velocity_gap_s << "velocity_known" << static_cast<int>(s.velocity_known);
  fsw << "residual_level_grey" << s.residual_level_grey << "prealign_level" << s.prealign_level;
  fsw << "temporal_residual_level_grey" << s.temporal_residual_level_grey;
  fsw << "observed_level_vertices" << s.observed_level_vertices;
  Eigen::Matrix<double, 3, 2> photometric;
  for (int j = 0; j < 3; ++j) photometric.row(j) << s.last_photometric[j].gain, s.last_photometric[j].bias_grey;
  fsw << "last_photometric" << toMat(photometric);
  fsw << "consecutive_failures" << s.consecutive_failures << "failures_total" << s.failures_total;
  fsw << "recoveries" << s.recoveries << "rejected_total" << s.rejected_total;
  fsw << "rectification_information" << toMat(s.rectification_information);
  fsw << "rectification_information_vector" << toMat(s.rectification_information_vector);
  fsw << "rectification_pairs" << s.rectification_pairs;
  Eigen::Matrix<double, 7, 1> rect;
  for (int c = 0; c < 6; ++c) rect[c] = s.rectification.row_shift_px[static_cast<size_t>(c)];
  rect[6] = s.rectification.per_disparity;
  fsw << "rectification" << toMat(rect) << "rectification_set" << static_cast<int>(s.rectification_set);
  fsw << "previous_obstacle_levels" << static_cast<int>(s.previous_obstacles.size());
  fsw << "previous_moving_levels" << static_cast<int>(s.previous_moving.size());
  fsw << "carried_moving_levels" << static_cast<int>(s.carried_moving.size());
  cv::Mat xy(static_cast<int>(state.trajectory_xy.size()), 2, CV_64F);
  for (int i = 0; i < xy.rows; ++i) {
    xy.at<double>(i, 0) = state.trajectory_xy[static_cast<size_t>(i)].x();
    xy.at<double>(i, 1) = state.trajectory_xy[static_cast<size_t>(i)].y();
  }
  fsw << "trajectory_xy" << xy;
  fsw.release();
}

SavedMapState MapStateFile::read(const std::string& directory, ElevationMap* map, OrthoTexture* ortho,
                                 PhotometricResidualMap* residual) {
  const fs::path dir(directory);
  if (!fs::is_directory(dir)) throw std::runtime_error("'" + directory + "' is not a directory");
  const std::string path = (dir / "state.yaml").string();
  if (!fs::exists(path)) throw std::runtime_error("'" + directory + "' holds no saved map (no state.yaml)");
  cv::FileStorage f;
  try {
    f.open(path, cv::FileStorage::READ);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("'" + path + "' is not readable YAML");
  }
  if (!f.isOpened()) throw std::runtime_error("cannot read '" + path + "'");
  SavedMapState out;
  EstimatorState& s = out.estimator;
  try {
    if (static_cast<int>(f["format_version"]) != kFormatVersion)
      throw std::runtime_error("format_version is not " + std::to_string(kFormatVersion));
    const double resolution = f["map_resolution_m"];
    const int tile_size = f["map_tile_size"];
    if (map && (std::abs(resolution - map->options().resolution_m) > 1e-9 || tile_size != map->options().tile_size))
      throw std::runtime_error("saved with grid_resolution_m " + std::to_string(resolution) + " and tiles of " +
                               std::to_string(tile_size) + ", this run uses " +
                               std::to_string(map->options().resolution_m) + " and " +
                               std::to_string(map->options().tile_size));
    out.sequence = static_cast<std::string>(f["sequence"]);
    out.next_sequence_frame = f["next_sequence_frame"];
    out.image_width_px = f["image_width_px"];
    out.image_height_px = f["image_height_px"];
    s.initialized = static_cast<int>(f["initialized"]) != 0;
    s.frame_counter = f["frame_counter"];
    s.ground_T_camera0 = readPose(f["ground_T_camera0"], "ground_T_camera0");
    s.ground_T_camera = readPose(f["ground_T_camera"], "ground_T_camera");
    s.last_camera_T_ground = readPose(f["last_camera_T_ground"], "last_camera_T_ground");
    s.last_stamp_s = f["last_stamp_s"];
    cv::Mat m;
    m = readMatrix(f["velocity"]);
    if (m.rows != 6 || m.cols != 1) throw std::runtime_error("velocity is not a 6-vector");
    cv::cv2eigen(m, s.velocity);
    s.velocity_gap_s = f["velocity_gap_s"];
    s.velocity_known = static_cast<int>(f["velocity_known"]) != 0;
    s.residual_level_grey = f["residual_level_grey"];
    s.prealign_level = f["prealign_level"];
    // absent from maps saved before 2026-12-07: unknown, learnt again from the next good frames
    if (!f["temporal_residual_level_grey"].empty()) s.temporal_residual_level_grey = f["temporal_residual_level_grey"];
    if (!f["observed_level_vertices"].empty()) s.observed_level_vertices = f["observed_level_vertices"];  // (2026-12-08)
    m = readMatrix(f["last_photometric"]);
    if (m.rows != 3 || m.cols != 2) throw std::runtime_error("last_photometric is not 3x2");
    for (int j = 0; j < 3; ++j) s.last_photometric[static_cast<size_t>(j)] = {m.at<double>(j, 0), m.at<double>(j, 1)};
    s.consecutive_failures = f["consecutive_failures"];
    s.failures_total = f["failures_total"];
    s.recoveries = f["recoveries"];
    s.rejected_total = f["rejected_total"];
    m = readMatrix(f["rectification_information"]);
    if (m.rows != 6 || m.cols != 6) throw std::runtime_error("rectification_information is not 6x6");
    cv::cv2eigen(m, s.rectification_information);
    m = readMatrix(f["rectification_information_vector"]);
    if (m.rows != 6 || m.cols != 1) throw std::runtime_error("rectification_information_vector is not a 6-vector");
    cv::cv2eigen(m, s.rectification_information_vector);
    s.rectification_pairs = f["rectification_pairs"];
    m = readMatrix(f["rectification"]);
    if (m.rows != 7 || m.cols != 1) throw std::runtime_error("rectification is not a 7-vector");
    for (int c = 0; c < 6; ++c) s.rectification.row_shift_px[static_cast<size_t>(c)] = m.at<double>(c);
    s.rectification.per_disparity = m.at<double>(6);
    s.rectification_set = static_cast<int>(f["rectification_set"]) != 0;
    const int levels = f["previous_obstacle_levels"];
    if (levels < 0 || levels > 16) throw std::runtime_error("previous_obstacle_levels out of range");
    // (absent from states written before 2026-12-04: nothing moving)
    const int moving_levels = f["previous_moving_levels"].empty() ? 0 : static_cast<int>(f["previous_moving_levels"]);
    if (moving_levels < 0 || moving_levels > 16) throw std::runtime_error("previous_moving_levels out of range");
    const int carried_levels = f["carried_moving_levels"].empty() ? 0 : static_cast<int>(f["carried_moving_levels"]);
    if (carried_levels < 0 || carried_levels > 16) throw std::runtime_error("carried_moving_levels out of range");
    m = readMatrix(f["trajectory_xy"]);
    if (!m.empty() && m.cols != 2) throw std::runtime_error("trajectory_xy is not N x 2");
    for (int i = 0; i < m.rows; ++i) out.trajectory_xy.emplace_back(m.at<double>(i, 0), m.at<double>(i, 1));
    s.previous_left = readImage((dir / "previous_left.tif").string(), CV_32FC1);
    s.previous_right = readImage((dir / "previous_right.tif").string(), CV_32FC1);
    s.last_left = readImage((dir / "last_left.tif").string(), CV_32FC1);
    for (int l = 0; l < levels; ++l)
      s.previous_obstacles.push_back(
          readImage((dir / ("previous_obstacles_" + std::to_string(l) + ".png")).string(), CV_8UC1));
    for (int l = 0; l < moving_levels; ++l)
      s.previous_moving.push_back(
          readImage((dir / ("previous_moving_" + std::to_string(l) + ".png")).string(), CV_8UC1));
    for (int l = 0; l < carried_levels; ++l)
      s.carried_moving.push_back(
          readImage((dir / ("carried_moving_" + std::to_string(l) + ".png")).string(), CV_8UC1));
    if (s.initialized && (s.previous_left.empty() || s.previous_right.empty()))
      throw std::runtime_error("previous_left.tif or previous_right.tif is missing");
    if (map) {
      if (!fs::is_directory(dir / "map")) throw std::runtime_error("the map/ directory is missing");
      ElevationMap loaded(map->options());
      const int tiles = loaded.loadArchive((dir / "map").string());
      const int expected = f["map_tiles"];
      if (tiles != expected)
        throw std::runtime_error("map/ holds " + std::to_string(tiles) + " tiles, state.yaml says " +
                                 std::to_string(expected));
      // into copies: nothing changes unless everything could be read
      std::unique_ptr<OrthoTexture> o = ortho ? std::make_unique<OrthoTexture>(*ortho) : nullptr;
      std::unique_ptr<PhotometricResidualMap> r = residual ? std::make_unique<PhotometricResidualMap>(*residual) : nullptr;
      readRecord((dir / "ortho.bin").string(), o.get(), static_cast<int>(f["ortho_saved"]) != 0);
      readRecord((dir / "residual.bin").string(), r.get(), static_cast<int>(f["residual_saved"]) != 0);
      *map = std::move(loaded);
      if (o) *ortho = std::move(*o);
      if (r) *residual = std::move(*r);
    }
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot resume from '" + directory + "': state.yaml: " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("cannot resume from '" + directory + "': " + e.what());
  }
  return out;
}

}  // namespace stereo_ground_dem
