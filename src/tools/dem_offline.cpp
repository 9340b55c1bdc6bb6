// dem_offline: the estimator without a ROS master.
//
//   dem_offline --left L.png --right R.png --calib FILE --out OUT [--config FILE] [--cameras 0,1|2,3]
//   dem_offline --sequence DIR --out OUT [--frames N] [--config FILE] [--cameras 0,1|2,3] [--quiet]
//               [--first-frame K] [--resume PREVIOUS_OUT]
//
// One-pair mode runs the stereo mode; sequence mode runs the incremental estimator over a
// KITTI-style folder (KittiSequence). Both write dem.tif / dem.yaml / dem_disparity_NNNNNN.png and
// pictures into OUT; errors are one line on stderr and a non-zero exit status. In sequence mode a
// frame that cannot be read or is refused is skipped with a one-line warning and counted
// (frames.csv status, summary.txt); the run succeeds when at least one frame was mapped.
// A sequence run also saves the map and the estimator's state in OUT/state (MapStateFile);
// `--resume PREVIOUS_OUT` continues that map from the frame after the one it stopped at (or from
// --first-frame), as if the frames had come in one run.
//
// Images of any type GreyConverter accepts (8/16-bit grey, BGR, BGRA; 16-bit scaled by its bit
// depth, `image_bit_depth` or detected from the first image) go through one GreyConverter.
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <numeric>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>

#include "stereo_ground_dem/CalibrationReader.hpp"
#include "stereo_ground_dem/GreyConverter.hpp"
#include "stereo_ground_dem/GroundAttitudeEstimator.hpp"
#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/OrthoTexture.hpp"
#include "stereo_ground_dem/PhotometricResidualMap.hpp"
#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/TraversabilityFilter.hpp"
#include "stereo_ground_dem/io/AllocatorTuning.hpp"
#include "stereo_ground_dem/io/DemExporter.hpp"
#include "stereo_ground_dem/io/DemPicture.hpp"
#include "stereo_ground_dem/io/DisparityPng.hpp"
#include "stereo_ground_dem/io/ImageFileReader.hpp"
#include "stereo_ground_dem/io/KittiSequence.hpp"
#include "stereo_ground_dem/io/MapStateFile.hpp"
#include "stereo_ground_dem/io/TrajectoryWriter.hpp"

using namespace stereo_ground_dem;

namespace {

const char* kUsage =
    "usage: dem_offline --left L.png --right R.png --calib FILE --out OUT [--config FILE] [--cameras P]\n"
    "       dem_offline --sequence DIR --out OUT [--frames N] [--config FILE] [--cameras P] [--quiet]\n"
    "                   [--first-frame K] [--resume PREVIOUS_OUT]\n"
    "  --config FILE  YAML file of parameters (see config/kitti.yaml)\n"
    "  --cameras P    camera pair of a KITTI calibration: 0,1 (grey) or 2,3 (colour); default: grey\n"
    "                 when present, else colour\n"
    "  --frames N     process N frames only\n"
    "  --first-frame K  start at frame K of the sequence (default 0, or where --resume stopped)\n"
    "  --resume DIR   continue the map a previous sequence run saved in DIR/state\n"
    "  --quiet        no per-frame progress lines\n"
    "       dem_offline --list-parameters [--config FILE]   every parameter (markdown table)\n";

/// Markdown table of every parameter: name, value (defaults, or after --config), tunable, meaning.
void listParameters(const std::string& config) {
  PipelineOptions o;
  const ParameterTable table(&o);
  if (!config.empty()) table.loadYaml(config);
  std::cout << "| name | value | tunable | meaning |\n|---|---|---|---|\n";
  for (const auto& e : table.entries()) {
    std::ostringstream v;
    if (e.type == ParameterTable::Type::kBool) v << (table.get(e) != 0.0 ? "true" : "false");
    else v << table.get(e);
    std::string d = e.description;
    for (size_t i = d.find('|'); i != std::string::npos; i = d.find('|', i + 2)) d.replace(i, 1, "\\|");
    std::cout << "| `" << e.name << "` | " << v.str() << " | " << (e.tunable ? "yes" : "") << " | " << d << " |\n";
  }
}

struct Args {
  std::string left, right, calib, sequence, out, config;
  CalibrationReader::CameraPair cameras = CalibrationReader::CameraPair::kAuto;
  int frames = -1;
  int first_frame = -1;  ///< -1: 0, or where the resumed run stopped
  std::string resume;
  bool quiet = false;
  bool list_parameters = false;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(k + " needs a value");
      return argv[++i];
    };
    if (k == "--left") a.left = value();
    else if (k == "--right") a.right = value();
    else if (k == "--calib") a.calib = value();
    else if (k == "--sequence") a.sequence = value();
    else if (k == "--out") a.out = value();
    else if (k == "--config") a.config = value();
    else if (k == "--cameras") {
      const std::string v = value();
      if (v == "0,1") a.cameras = CalibrationReader::CameraPair::kGray;
      else if (v == "2,3") a.cameras = CalibrationReader::CameraPair::kColor;
      else throw std::invalid_argument("--cameras takes 0,1 or 2,3, got '" + v + "'");
    }
    else if (k == "--frames") {
      const std::string v = value();
      char* end = nullptr;
      const long n = std::strtol(v.c_str(), &end, 10);
      if (*end != '\0' || n < 1) throw std::invalid_argument("--frames needs a positive integer, got '" + v + "'");
      a.frames = static_cast<int>(n);
    } else if (k == "--first-frame") {
      const std::string v = value();
      char* end = nullptr;
      const long n = std::strtol(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0' || n < 0 || n > 100000000)
        throw std::invalid_argument("--first-frame needs a non-negative integer, got '" + v + "'");
      a.first_frame = static_cast<int>(n);
    } else if (k == "--resume") a.resume = value();
    else if (k == "--quiet") a.quiet = true;
    else if (k == "--list-parameters") a.list_parameters = true;
    else if (k == "-h" || k == "--help") {
      std::cout << kUsage;
      std::exit(0);
    } else {
      throw std::invalid_argument("unknown argument '" + k + "'");
    }
  }
  if (a.list_parameters) return a;
  if (a.out.empty()) throw std::invalid_argument("--out is required");
  const bool pair = !a.left.empty() || !a.right.empty() || !a.calib.empty();
  if (pair && !a.sequence.empty()) throw std::invalid_argument("use either --left/--right/--calib or --sequence");
  if (!pair && a.sequence.empty()) throw std::invalid_argument("give --left/--right/--calib or --sequence");
  if (pair && (a.left.empty() || a.right.empty() || a.calib.empty())) {
    throw std::invalid_argument("one-pair mode needs --left, --right and --calib");
  }
  if (pair && (!a.resume.empty() || a.first_frame >= 0))
    throw std::invalid_argument("--resume and --first-frame need --sequence");
  return a;
}

cv::Mat toMat(const GroundGrid& g, const Eigen::VectorXd& v) {
  cv::Mat m(g.rows, g.cols, CV_32F);
  for (int r = 0; r < g.rows; ++r)
    for (int c = 0; c < g.cols; ++c) m.at<float>(r, c) = static_cast<float>(v[g.index(r, c)]);
  return m;
}

double peakMemoryMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;
}

void warn(const std::string& what) { std::fprintf(stderr, "dem_offline: warning: %s\n", what.c_str()); }

void writeOverlay(const std::string& path, const cv::Mat& image, const cv::Mat& disparity, int bit_depth) {
  DemPictureOptions po;
  po.image_bit_depth = bit_depth;
  cv::Mat d = disparity.clone();
  d.setTo(std::numeric_limits<float>::quiet_NaN(), disparity <= 0.0f);
  DemPicture::save(path, DemPicture::overlayOnImage(image, d, std::numeric_limits<double>::quiet_NaN(),
                                                     std::numeric_limits<double>::quiet_NaN(),
                                                     "DEM-implied disparity [px]", po));
}

/// Obstacle cells are lethal (traversability 0, probability of being traversable 0) whatever the
/// elevation layer holds there.
void markObstacles(DemExport* dem) {
  if (dem->obstacles.empty()) return;
  if (!dem->traversability.empty()) dem->traversability.setTo(0.0f, dem->obstacles == 1.0f);
  if (!dem->traversability_confidence.empty()) dem->traversability_confidence.setTo(0.0f, dem->obstacles == 1.0f);
}

/// The left image with the obstacle pixels (red) and the obstacle layer's vertices (yellow dots).
void writeObstacleOverlay(const std::string& path, const cv::Mat& image, int bit_depth, const cv::Mat& excluded,
                          const StereoResult& r, const StereoRig& rig) {
  cv::Mat vis = GreyConverter::toBgr8(image, bit_depth);
  cv::Mat red(vis.size(), vis.type(), cv::Scalar(0, 0, 255));
  cv::Mat blended;
  cv::addWeighted(vis, 0.5, red, 0.5, 0.0, blended);
  blended.copyTo(vis, excluded);
  const Eigen::Isometry3d camera_T_ground = r.ground_T_camera.inverse();
  for (int v = 0; v < r.grid.vertexCount(); ++v) {
    if (!(r.obstacle[v] == 1.0)) continue;
    const Eigen::Vector2d xy = r.grid.position(v);
    const Eigen::Vector3d pc = camera_T_ground * Eigen::Vector3d(xy.x(), xy.y(), 0.0);
    if (pc.z() <= 0.5) continue;
    cv::circle(vis, cv::Point2d(rig.fx * pc.x() / pc.z() + rig.cx, rig.fy * pc.y() / pc.z() + rig.cy), 2,
               cv::Scalar(0, 255, 255), cv::FILLED);
  }
  cv::putText(vis, "obstacle pixels (red), obstacle-layer vertices (yellow)", cv::Point(10, 22),
              cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(255, 255, 255), 2);
  DemPicture::save(path, vis);
}

cv::Mat readImage(const std::string& path) {
  std::string why;
  const cv::Mat m = ImageFileReader::read(path, &why);
  if (m.empty()) throw std::runtime_error(why);
  return m;
}

/// The grey float image the estimators take; a refused image throws naming its path.
cv::Mat toGrey(GreyConverter* conv, const cv::Mat& image, const std::string& path) {
  try {
    return conv->convert(image);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("image '" + path + "': " + e.what());
  }
}

/// Creates `dir` and checks that a file can be written in it (before any work is done).
void checkOutputDirectory(const std::string& dir) {
  DemExporter::makeDirectories(dir);
  const std::string probe = dir + "/.dem_offline_probe";
  std::ofstream f(probe);
  f << "x";
  f.close();
  if (!f) {
    throw std::runtime_error("cannot write into output directory '" + dir + "': " + std::strerror(errno));
  }
  std::remove(probe.c_str());
}

std::string frameFileName(const char* stem, int frame, const char* ext) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%s_%06d.%s", stem, frame, ext);
  return buf;
}

int runPair(const Args& a) {
  PipelineOptions o = ParameterTable::load(a.config);
  StereoRig rig = CalibrationReader::read(a.calib, a.cameras);
  if (!rig.rectificationWarning().empty()) warn(rig.rectificationWarning());
  const cv::Mat left = readImage(a.left);
  const cv::Mat right = readImage(a.right);
  if (left.size() != right.size()) {
    std::ostringstream os;
    os << "left image " << left.cols << "x" << left.rows << " and right image " << right.cols << "x" << right.rows
       << " differ in size";
    throw std::runtime_error(os.str());
  }
  try {
    rig = rig.withImageSize(left.cols, left.rows);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("calibration '" + a.calib + "' does not fit image '" + a.left + "': " + e.what());
  }
  GreyConverter conv(o.input);
  const cv::Mat grey_left = toGrey(&conv, left, a.left), grey_right = toGrey(&conv, right, a.right);
  checkOutputDirectory(a.out);
  const StereoEstimator est(rig, o.estimator.stereo);
  const auto t0 = std::chrono::steady_clock::now();
  const ImagePyramid pl = est.makeStereoPyramid(grey_left), pr = est.makeStereoPyramid(grey_right);
  const StereoResult r = est.estimate(pl, pr);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!r.ok) throw std::runtime_error("estimation failed: " + r.message);
  DemExport dem;
  dem.grid = r.grid;
  dem.elevation = toMat(r.grid, r.heights);
  Eigen::VectorXd var = r.information.cwiseInverse();
  for (int v = 0; v < var.size(); ++v)
    if (!std::isfinite(r.heights[v]) || !(r.information[v] > 0)) var[v] = std::numeric_limits<double>::quiet_NaN();
  dem.variance = toMat(r.grid, var);
  dem.traversability = TraversabilityFilter(o.traversability).compute(r.grid, dem.elevation).traversability;
  dem.obstacles = toMat(r.grid, r.obstacle);
  dem.obstacle_height = toMat(r.grid, r.obstacle_height);
  markObstacles(&dem);
  dem.ground_T_camera0 = r.ground_T_camera;
  dem.trajectory_xy = {r.ground_T_camera.translation().head<2>()};
  dem.extra = {{"mode", "stereo (one pair)"}, {"left_image", a.left}, {"right_image", a.right}};
  DemExporter::write(a.out, dem);
  const cv::Mat disp = est.impliedDisparity(r, pl);
  DisparityPng::write(a.out + "/dem_disparity_000000.png", disp);
  writeOverlay(a.out + "/dem_disparity_overlay.png", left, disp, conv.bitDepth());
  writeObstacleOverlay(a.out + "/obstacles_overlay.png", left, conv.bitDepth(), r.obstacles.excluded[0], r, rig);
  int known = 0;
  for (int v = 0; v < r.heights.size(); ++v) known += std::isfinite(r.heights[v]);
  std::printf("stereo mode: %.1f ms, %d of %d vertices observed, gain %.4f, bias %.2f grey, camera %.3f m above the ground\n",
              ms, known, r.grid.vertexCount(), r.photometric.gain, r.photometric.bias_grey,
              r.ground_T_camera.translation().z());
  std::printf("wrote %s/{dem.tif, dem.yaml, variance.tif, traversability.tif, dem_height.png, traversability.png, "
              "mesh.ply, dem_disparity_000000.png, dem_disparity_overlay.png, obstacles.tif, obstacle_height.tif, "
              "obstacles_overlay.png}\n",
              a.out.c_str());
  return 0;
}

int runSequence(const Args& a) {
  PipelineOptions o = ParameterTable::load(a.config);
  KittiSequenceOptions so;
  so.cameras = a.cameras;
  so.read_ground_truth = false;  // not needed for mapping; sgd_evaluate reads it
  const KittiSequence seq = KittiSequence::open(a.sequence, so);
  for (const std::string& w : seq.warnings()) warn(w);
  o.estimator.motion_information = false;  // only the ROS odometry covariance uses it
  IncrementalEstimator est(seq.rig(), o.estimator);
  const GroundAttitudeEstimator ground_attitude(o.attitude);
  OrthoTextureOptions ortho_options = o.ortho;
  ortho_options.keep_radius_m = o.estimator.map.keep_radius_m;
  OrthoTexture ortho(ortho_options);
  PhotometricResidualOptions residual_options = o.residual;
  residual_options.keep_radius_m = o.estimator.map.keep_radius_m;
  PhotometricResidualMap residual(est.map().options().resolution_m, residual_options);
  // --resume: the previous run's map, layers and estimator state (OUT/state, or the state itself)
  SavedMapState saved;
  std::string resume_dir;
  if (!a.resume.empty()) {
    resume_dir = MapStateFile::exists(a.resume + "/state") ? a.resume + "/state" : a.resume;
    saved = MapStateFile::read(resume_dir, &est.map(), ortho_options.enabled ? &ortho : nullptr,
                               residual_options.enabled ? &residual : nullptr);
    if (saved.image_width_px != seq.rig().width || saved.image_height_px != seq.rig().height) {
      std::ostringstream os;
      os << "cannot resume from '" << resume_dir << "': saved for " << saved.image_width_px << "x"
         << saved.image_height_px << " images, this sequence has " << seq.rig().width << "x" << seq.rig().height;
      throw std::runtime_error(os.str());
    }
    try {
      est.restore(saved.estimator);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error("cannot resume from '" + resume_dir + "': " + e.what());
    }
  }
  const int first = a.first_frame >= 0 ? a.first_frame : std::max(0, saved.next_sequence_frame);
  if (first >= seq.size())
    throw std::invalid_argument("the first frame " + std::to_string(first) + " is past the sequence's " +
                                std::to_string(seq.size()) + " frames" +
                                (a.resume.empty() ? std::string() : " (the resumed run stopped there)"));
  // A state saved on another clock (the node's ROS stamps) or resumed at another frame than the
  // next one: the saved velocity and stamp do not apply; the motion is searched from the saved pose.
  if (!a.resume.empty() && saved.estimator.initialized && std::isfinite(seq.stamp(first)) &&
      (first != saved.next_sequence_frame || !(seq.stamp(first) > saved.estimator.last_stamp_s))) {
    saved.estimator.rebaseClock(seq.stamp(first), o.estimator.nominal_frame_period_s);
    est.restore(saved.estimator);
    warn("resuming at frame " + std::to_string(first) + " on another clock than the saved state's: the motion is "
         "searched from the saved pose");
  }
  const int n = a.frames > 0 ? std::min(a.frames, seq.size() - first) : seq.size() - first;
  checkOutputDirectory(a.out);
  constexpr double kDeg = 180.0 / M_PI;
  GreyConverter conv(o.input);
  std::ofstream timing(a.out + "/timing.csv");
  timing << "frame,ms,pyramid_ms,prealign_ms,obstacle_ms,joint_ms,other_ms,evaluations,ortho_ms,residual_ms\n";
  std::ofstream frames(a.out + "/frames.csv");
  // every Gauss-Newton pass of every frame, in the order run: where a frame's time goes
  std::ofstream alignments(a.out + "/alignments.csv");
  alignments << "frame,pass,level,pairs,motion,heights,iterations,accepted_steps,converged,evaluations,setup_ms,"
                "evaluate_ms,raster_ms,solve_ms,working_triangles,active_vertices,valid_pixels,initial_cost,final_cost,stalled,"
                "final_step_evaluations\n";
  frames << "frame,stamp_s,status,ms,median_abs_residual_grey,fused_vertices,obstacle_pixels,gain_lr,bias_lr,rectification_max_px,stereo_residual_grey,temporal_residual_grey,moving_pixels,ground_height_m,ground_pitch_deg,ground_roll_deg,prealign_shift_m,prealign_rejected,prealign_discarded,carried_moving_pixels,hidden_pixels,far_pixels,far_seeded_vertices,far_carved_vertices,rising_seeded_vertices,far_refuted_vertices,repeat_from_prediction,message\n";
  std::vector<Eigen::Isometry3d> poses, tum_poses;
  std::vector<double> tum_stamps, ms_all;
  std::vector<Eigen::Vector2d> xy = saved.trajectory_xy;
  int failures = 0, rejected = 0, unreadable = 0, mapped = 0, first_mapped = -1;
  cv::Mat disparity0, image0;
  for (int i = first; i < first + n; ++i) {
    const double stamp = seq.stamp(i);
    cv::Mat left, right, grey_left, grey_right;
    std::string problem;
    bool readable = seq.tryRead(i, &left, &right, &problem);
    if (readable) {
      try {
        grey_left = conv.convert(left);
        grey_right = conv.convert(right);
      } catch (const std::invalid_argument& e) {
        problem = std::string(grey_left.empty() ? "left" : "right") + " image: " + e.what();
      }
    }
    // A frame that is unreadable or refused by the converter goes to the estimator as an empty
    // pair: nothing is estimated, the map is untouched, the pose is the prediction.
    FrameResult fr = problem.empty() ? est.processFrame(grey_left, grey_right, stamp)
                                     : est.processFrame(cv::Mat(), cv::Mat(), stamp);
    if (!problem.empty()) fr.message = problem;
    const std::string status = readable ? toString(fr.status) : "unreadable";
    unreadable += !readable;
    rejected += readable && fr.status == FrameStatus::kRejectedInput;
    failures += fr.status == FrameStatus::kFailed;
    const bool good = fr.status == FrameStatus::kInitialized || fr.status == FrameStatus::kTracked ||
                      fr.status == FrameStatus::kRecovered;
    mapped += good;
    if (!good && fr.status != FrameStatus::kFailed) warn("frame " + std::to_string(i) + " skipped: " + fr.message);
    if (good && first_mapped < 0) {  // initialized, or the first of a resumed run
      first_mapped = i;
      disparity0 = est.surfaceDisparity(fr.ground_T_camera);
      image0 = left;
    }
    poses.push_back(fr.camera0_T_camera);
    if (std::isfinite(stamp)) {
      tum_stamps.push_back(stamp);
      tum_poses.push_back(fr.camera0_T_camera);
    }
    ms_all.push_back(fr.time_ms);
    if (est.initialized()) xy.push_back(fr.ground_T_camera.translation().head<2>());
    // The ortho-texture: this frame's left image draped on the map just fused (not in time_ms:
    // it is a product layer, timed on its own).
    double ortho_ms = 0.0;
    if (good && ortho_options.enabled) {
      const auto t0 = std::chrono::steady_clock::now();
      ortho.update(est.map(), fr.window, est.lastLeftImage(), seq.rig(),
                   fr.ground_T_camera, fr.photometric[1]);
      ortho.evictFarFrom(fr.ground_T_camera.translation().x(), fr.ground_T_camera.translation().y());
      ortho_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    double residual_ms = 0.0;
    if (good && residual_options.enabled) {
      const auto t0 = std::chrono::steady_clock::now();
      // the temporal pair only where the motion was estimated against the previous frame
      residual.update(est.map(), fr.window, est.lastLeftImage(), est.lastRightImage(), seq.rig(), fr.ground_T_camera,
                      fr.rectification, fr.photometric[0],
                      fr.status == FrameStatus::kTracked ? &fr.photometric[1] : nullptr, est.lastObstacleMask(),
                      est.lastMovingMask());
      residual.evictFarFrom(fr.ground_T_camera.translation().x(), fr.ground_T_camera.translation().y());
      residual_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    int evaluations = 0;
    for (const AlignmentReport& r : fr.reports) evaluations += r.evaluations;
    for (size_t k = 0; k < fr.reports.size(); ++k) {
      const AlignmentReport& r = fr.reports[k];
      alignments << i << "," << k << "," << r.level << "," << r.pairs << "," << r.motion << "," << r.heights << ","
                 << r.iterations << "," << r.accepted_steps << "," << r.converged << "," << r.evaluations << ","
                 << r.setup_ms << "," << r.evaluate_ms << "," << r.raster_ms << "," << r.solve_ms << ","
                 << r.working_triangles << "," << r.active_vertices << "," << r.valid_pixels << "," << r.initial_cost
                 << "," << r.final_cost << "," << r.stalled << "," << r.final_step_evaluations << "\n";
    }
    timing << i << "," << fr.time_ms << "," << fr.pyramid_ms << "," << fr.prealign_ms << "," << fr.obstacle_ms << ","
           << fr.joint_ms << "," << fr.time_ms - fr.pyramid_ms - fr.prealign_ms - fr.obstacle_ms - fr.joint_ms << ","
           << evaluations << "," << ortho_ms << "," << residual_ms << "\n";
    // The camera above the local ground (the fused map around it), for mapped frames.
    const GroundAttitudeEstimate attitude =
        good ? ground_attitude.estimate(est.map(), fr.ground_T_camera) : GroundAttitudeEstimate();
    std::string msg = fr.message;
    std::replace(msg.begin(), msg.end(), ',', ';');
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    frames << i << "," << stamp << "," << status << "," << fr.time_ms << "," << fr.median_abs_residual_grey << ","
           << fr.fused_vertices << "," << fr.obstacle_pixels << "," << fr.photometric[0].gain << ","
           << fr.photometric[0].bias_grey << "," << fr.rectification.maxAbsPx(seq.rig(), 0.0) << ","
           << fr.stereo_residual_grey << "," << fr.temporal_residual_grey << "," << fr.moving_pixels << ","
           << attitude.height_m << "," << attitude.pitch_rad * kDeg << "," << attitude.roll_rad * kDeg << ","
           << fr.prealign_shift_m << "," << (fr.prealign_rejected ? 1 : 0) << "," << fr.prealign_discarded << "," << fr.carried_moving_pixels << "," << fr.hidden_pixels << "," << fr.far_pixels << "," << fr.far_seeded_vertices << "," << fr.far_carved_vertices << "," << fr.rising_seeded_vertices << "," << fr.far_refuted_vertices << "," << (fr.repeat_from_prediction ? 1 : 0) << "," << msg
           << "\n";
    if (!a.quiet) {
      const Eigen::Vector3d t = fr.camera0_T_camera.translation();
      std::printf("frame %4d/%d %7.1f ms  %-14s  x %7.2f y %7.2f z %7.2f m%s%s\n", i + 1, first + n, fr.time_ms, status.c_str(),
                  t.x(), t.y(), t.z(), fr.message.empty() ? "" : "  ", fr.message.c_str());
      std::fflush(stdout);
    }
  }
  timing.close();
  frames.close();
  if (!timing || !frames || !alignments) {
    throw std::runtime_error("cannot write timing.csv, frames.csv or alignments.csv in '" + a.out + "'");
  }
  std::vector<double> sorted = ms_all;
  std::sort(sorted.begin(), sorted.end());
  const double mean = std::accumulate(ms_all.begin(), ms_all.end(), 0.0) / ms_all.size();
  const double median = sorted[sorted.size() / 2];
  const ElevationMap& map = est.map();
  std::ostringstream summary;
  summary << "frames: " << n << "\nfirst_frame: " << first << "\nresumed_from: " << (resume_dir.empty() ? "-" : resume_dir)
          << "\nmapped: " << mapped << "\nfirst_mapped_frame: " << first_mapped
          << "\nfailed: " << failures << "\nrejected_input: " << rejected << "\nunreadable: " << unreadable
          << "\nskipped: " << rejected + unreadable << "\nrecovered: " << est.recoveries()
          << "\ncameras: " << (seq.cameras() == CalibrationReader::CameraPair::kAuto ? "l,r" : CalibrationReader::name(seq.cameras())) << "\nimage_bit_depth: " << conv.bitDepth()
          << "\nmean_ms: " << mean << "\nmedian_ms: " << median << "\npeak_memory_mb: " << peakMemoryMb()
          << "\nmap_tiles: " << map.tileCount() << "\nmap_memory_mb: " << map.memoryBytes() / 1048576.0 << "\n";
  std::ofstream(a.out + "/summary.txt") << summary.str();
  if (mapped == 0) {
    std::ostringstream os;
    os << "no frame could be mapped (" << n << " frames: " << unreadable << " unreadable, " << rejected
       << " rejected, " << failures << " failed; see " << a.out << "/frames.csv)";
    throw std::runtime_error(os.str());
  }
  TrajectoryWriter::writeKitti(a.out + "/trajectory_kitti.txt", poses);
  TrajectoryWriter::writeTum(a.out + "/trajectory_tum.txt", tum_stamps, tum_poses);
  DemExport dem;
  dem.grid = map.knownBounds();
  dem.elevation = map.layer(ElevationMap::Layer::kElevation, dem.grid);
  dem.variance = map.layer(ElevationMap::Layer::kVariance, dem.grid);
  // heights the images kept contradicting (ground the mesh draped behind a guardrail) are unknown
  if (residual_options.enabled) residual.unpublishContradicted(dem.grid, {&dem.elevation, &dem.variance});
  {
    const TraversabilityFilter filter(o.traversability);
    const TraversabilityLayers t = filter.compute(dem.grid, dem.elevation);
    dem.traversability = t.traversability;
    dem.traversability_confidence = filter.probability(dem.grid, t, dem.variance);
  }
  dem.obstacles = map.layer(ElevationMap::Layer::kObstacle, dem.grid);
  dem.obstacle_height = map.layer(ElevationMap::Layer::kObstacleHeight, dem.grid);
  markObstacles(&dem);
  if (residual_options.enabled) {
    dem.residual = residual.layer(PhotometricResidualMap::Layer::kResidual, dem.grid);
    dem.residual_outlier_rate = residual.layer(PhotometricResidualMap::Layer::kOutlierRate, dem.grid);
  }
  if (ortho_options.enabled) {
    dem.intensity = ortho.sample(dem.grid);
    dem.ortho = ortho.raster(&dem.ortho_grid);
  }
  dem.ground_T_camera0 = est.groundTCamera0();
  dem.trajectory_xy = xy;
  dem.extra = {{"mode", "incremental (sequence)"}, {"sequence", a.sequence},
               {"first_mapped_frame", std::to_string(first_mapped)}, {"first_frame", std::to_string(first)},
               {"resumed_from", resume_dir.empty() ? "-" : resume_dir}};
  DemExporter::write(a.out, dem);
  // the map and the estimator's state, for --resume
  SavedMapState state;
  state.estimator = est.state();
  state.trajectory_xy = xy;
  state.sequence = a.sequence;
  state.next_sequence_frame = first + n;
  state.image_width_px = seq.rig().width;
  state.image_height_px = seq.rig().height;
  MapStateFile::write(a.out + "/state", state, map, ortho_options.enabled ? &ortho : nullptr,
                      residual_options.enabled ? &residual : nullptr);
  const std::string disparity_name = frameFileName("dem_disparity", first_mapped, "png");
  DisparityPng::write(a.out + "/" + disparity_name, disparity0);
  writeOverlay(a.out + "/dem_disparity_overlay.png", image0, disparity0, conv.bitDepth());
  std::printf("%d frames (%d mapped, %d failed, %d rejected, %d unreadable), %.1f ms mean, %.1f ms median per frame, "
              "peak memory %.0f MB\n",
              n, mapped, failures, rejected, unreadable, mean, median, peakMemoryMb());
  std::printf("wrote %s/{dem.tif, dem.yaml, variance.tif, traversability.tif, dem_height.png, traversability.png, "
              "mesh.ply, traversability_confidence.tif, obstacles.tif, obstacle_height.tif, intensity.tif, ortho.tif, ortho.png, residual.tif, residual_outlier_rate.tif, %s, dem_disparity_overlay.png, trajectory_kitti.txt, "
              "trajectory_tum.txt, timing.csv, frames.csv, alignments.csv, summary.txt, state/}\n",
              a.out.c_str(), disparity_name.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  AllocatorTuning::apply();  // frame buffers reused, not faulted in again every frame
  // Our errors are one line each; OpenCV's own warnings (e.g. on a missing image) would add more.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  Args a;
  try {
    a = parse(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dem_offline: %s\n%s", e.what(), kUsage);
    return 2;
  }
  try {
    if (a.list_parameters) {
      listParameters(a.config);
      return 0;
    }
    return a.sequence.empty() ? runPair(a) : runSequence(a);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dem_offline: %s\n", e.what());
    return 1;
  }
}
