// sgd_evaluate: accuracy of a dem_offline result against ground truth.
//
//   sgd_evaluate --sequence SEQ --result OUT [--config FILE] [--report FILE]
//
// Trajectory (OUT/trajectory_kitti.txt vs SEQ/poses.txt): end-point drift in % of the path,
// per-frame relative errors, KITTI-style segment errors. For synthetic sequences (SEQ/scene.yaml
// present): DEM height errors by the distance at which vertices were seen, coverage, and
// traversability precision/recall against the exact terrain. Writes OUT/evaluation.yaml.
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <fstream>
#include <iostream>
#include <sstream>
#include <sys/stat.h>

#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/TraversabilityFilter.hpp"
#include "stereo_ground_dem/eval/DemMetrics.hpp"
#include "stereo_ground_dem/eval/TrajectoryMetrics.hpp"
#include "stereo_ground_dem/io/DemMetadata.hpp"
#include "stereo_ground_dem/io/DemPicture.hpp"
#include "stereo_ground_dem/io/GeoTiff.hpp"
#include "stereo_ground_dem/io/KittiSequence.hpp"
#include "stereo_ground_dem/io/TrajectoryWriter.hpp"

using namespace stereo_ground_dem;

namespace {
bool exists(const std::string& p) {
  struct stat st {};
  return stat(p.c_str(), &st) == 0;
}
Eigen::Isometry3d readMatrix16(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open '" + path + "'");
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i)
    if (!(in >> m(i / 4, i % 4))) throw std::runtime_error("'" + path + "' does not hold 16 numbers");
  Eigen::Isometry3d t;
  t.matrix() = m;
  return t;
}
}  // namespace

int main(int argc, char** argv) {
  std::string seq_dir, result, config, report;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "sgd_evaluate: %s needs a value\n", k.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (k == "--sequence") seq_dir = value();
    else if (k == "--result") result = value();
    else if (k == "--config") config = value();
    else if (k == "--report") report = value();
    else {
      std::fprintf(stderr, "sgd_evaluate: unknown argument '%s'\nusage: sgd_evaluate --sequence SEQ --result OUT [--config FILE] [--report FILE]\n", k.c_str());
      return 2;
    }
  }
  if (seq_dir.empty() || result.empty()) {
    std::fprintf(stderr, "usage: sgd_evaluate --sequence SEQ --result OUT [--config FILE] [--report FILE]\n");
    return 2;
  }
  if (report.empty()) report = result + "/evaluation.yaml";
  try {
    const KittiSequence seq = KittiSequence::open(seq_dir);
    if (seq.groundTruth().empty()) throw std::runtime_error("sequence '" + seq_dir + "' has no poses.txt");
    const auto est = TrajectoryWriter::readKitti(result + "/trajectory_kitti.txt");
    const TrajectoryMetrics tm = TrajectoryMetrics::compute(est, seq.groundTruth());
    std::ostringstream y;
    y << "frames: " << tm.frames << "\npath_length_m: " << tm.path_length_m
      << "\nend_translation_error_m: " << tm.end_translation_error_m << "\nend_drift_pct: " << tm.end_drift_pct
      << "\nend_rotation_error_deg: " << tm.end_rotation_error_deg
      << "\nmax_rotation_error_deg: " << tm.max_rotation_error_deg
      << "\nrelative_translation_error_m: {mean: " << tm.rel_translation_mean_m << ", median: " << tm.rel_translation_median_m
      << ", max: " << tm.rel_translation_max_m << "}\nrelative_rotation_error_deg: {mean: " << tm.rel_rotation_mean_deg
      << ", median: " << tm.rel_rotation_median_deg << ", max: " << tm.rel_rotation_max_deg << "}\nsegments:\n";
    for (const auto& s : tm.segments) {
      y << "  - {length_m: " << s.length_m << ", count: " << s.count << ", translation_pct: " << s.translation_pct
        << ", rotation_deg_per_m: " << s.rotation_deg_per_m << "}\n";
    }
    std::printf("trajectory: %d frames, %.1f m; end-point drift %.3f m = %.2f %% of the path; end rotation error %.3f deg\n",
                tm.frames, tm.path_length_m, tm.end_translation_error_m, tm.end_drift_pct, tm.end_rotation_error_deg);
    std::printf("  per frame: translation error median %.4f m (max %.4f), rotation error median %.4f deg (max %.4f)\n",
                tm.rel_translation_median_m, tm.rel_translation_max_m, tm.rel_rotation_median_deg, tm.rel_rotation_max_deg);
    for (const auto& s : tm.segments) {
      std::printf("  segments of %3.0f m: %6.3f %% translation, %.4f deg/m rotation (%d)\n", s.length_m,
                  s.translation_pct, s.rotation_deg_per_m, s.count);
    }
    if (exists(seq_dir + "/scene.yaml")) {
      PipelineOptions o;
      if (!config.empty()) ParameterTable(&o).loadYaml(config);
      const sim::SyntheticScene scene = sim::SyntheticScene::fromYaml(seq_dir + "/scene.yaml");
      GroundGrid grid;
      const cv::Mat dem = GeoTiff::read(result + "/dem.tif", &grid);
      const DemMetadata meta = DemMetadata::read(result + "/dem.yaml");
      cv::Mat trav, obstacles;
      if (exists(result + "/traversability.tif")) trav = GeoTiff::read(result + "/traversability.tif");
      if (exists(result + "/obstacles.tif")) obstacles = GeoTiff::read(result + "/obstacles.tif");
      const Eigen::Isometry3d true_g_T_c0 = readMatrix16(seq_dir + "/ground_T_camera0.txt");
      std::vector<double> times;
      for (int i = 0; i < seq.size(); ++i) times.push_back(seq.stamp(i));
      // the true terrain on the estimated grid -> the true traversability
      const Eigen::Isometry3d true_T_est = true_g_T_c0 * meta.ground_T_camera0.inverse();
      const Eigen::Isometry3d est_T_true = true_T_est.inverse();
      cv::Mat truth(grid.rows, grid.cols, CV_32F);
      for (int r = 0; r < grid.rows; ++r)
        for (int c = 0; c < grid.cols; ++c) {
          Eigen::Vector3d p = true_T_est * Eigen::Vector3d(grid.xOfCol(c), grid.yOfRow(r), 0.0);
          p.z() = scene.terrainHeight(p.x(), p.y());
          truth.at<float>(r, c) = static_cast<float>((est_T_true * p).z());
        }
      const cv::Mat true_trav = TraversabilityFilter(o.traversability).compute(grid, truth).traversability;
      const std::vector<Eigen::Isometry3d> poses(seq.groundTruth().begin(),
                                                 seq.groundTruth().begin() + std::min<size_t>(est.size(), seq.groundTruth().size()));
      const DemMetrics dm = DemMetrics::compute(grid, dem, trav, meta.ground_T_camera0, scene, true_g_T_c0, poses,
                                                times, seq.rig(), true_trav, obstacles);
      y << "dem:\n  known_vertices: " << dm.known_vertices << "\n  obstacle_vertices: " << dm.obstacle_vertices << "\n  bins:\n";
      std::printf("DEM: %d known vertices (%d inside obstacle footprints, excluded)\n", dm.known_vertices, dm.obstacle_vertices);
      auto line = [&](const HeightErrorStats& s) {
        y << "    - {seen_within_m: [" << s.min_depth_m << ", " << s.max_depth_m << "], count: " << s.count
          << ", median_m: " << s.median_m << ", rmse_m: " << s.rmse_m << ", p95_m: " << s.p95_m
          << ", coverage: " << s.coverage << "}\n";
        std::printf("  seen within %2.0f-%2.0f m: %5d vertices, |error| median %.2f cm, RMSE %.2f cm, 95th %.2f cm, coverage %.0f %%\n",
                    s.min_depth_m, s.max_depth_m, s.count, 100 * s.median_m, 100 * s.rmse_m, 100 * s.p95_m,
                    100 * s.coverage);
      };
      for (const auto& s : dm.bins) line(s);
      y << "  within_20m:\n";
      line(dm.within_20m);
      GeoTiff::write(result + "/height_error.tif", dm.signed_error, grid, "height_error");
      DemPictureOptions po;
      po.min_value = -0.10;
      po.max_value = 0.10;
      po.hillshade = false;
      po.height_colormap = cv::COLORMAP_JET;
      po.title = "Height error: estimate - truth [m]";
      DemPicture::save(result + "/height_error.png", DemPicture::heightPicture(dm.signed_error, grid, po));
      y << "  traversability: {compared: " << dm.trav_compared << ", precision: " << dm.trav_precision
        << ", recall: " << dm.trav_recall << ", accuracy: " << dm.trav_accuracy << "}\n";
      std::printf("traversability (blocked < 0.5): precision %.3f, recall %.3f, accuracy %.3f over %d vertices\n",
                  dm.trav_precision, dm.trav_recall, dm.trav_accuracy, dm.trav_compared);
      if (!obstacles.empty()) {
        // obstacle_check.png: the classes on the grid (rows along y: flipped so that +y is up)
        static const cv::Vec3b kColour[7] = {{255, 255, 255}, {200, 200, 200}, {0, 0, 230}, {230, 200, 0},
                                             {0, 140, 255}, {0, 170, 0}, {200, 0, 0}};
        cv::Mat pic(grid.rows, grid.cols, CV_8UC3);
        for (int r = 0; r < grid.rows; ++r)
          for (int c = 0; c < grid.cols; ++c)
            pic.at<cv::Vec3b>(grid.rows - 1 - r, c) = kColour[dm.obstacle_class.at<uint8_t>(r, c)];
        cv::resize(pic, pic, cv::Size(), 4, 4, cv::INTER_NEAREST);
        cv::imwrite(result + "/obstacle_check.png", pic);
        auto pct = [](int a, int b) { return b > 0 ? 100.0 * a / b : 0.0; };
        y << "  obstacles: {free_cells: " << dm.obs_free_known << ", free_flagged_pct: " << pct(dm.obs_free_flagged, dm.obs_free_known)
          << ", left_by_movers_seen_again: " << dm.obs_path_seen << ", ghost_pct: " << pct(dm.obs_path_ghost, dm.obs_path_seen)
          << ", static_cells: " << dm.obs_static_known << ", static_marked_pct: " << pct(dm.obs_static_marked, dm.obs_static_known)
          << ", static_in_view: " << dm.obs_static_in_view
          << ", static_recall_pct: " << pct(dm.obs_static_in_view_marked, dm.obs_static_in_view) << "}\n";
        std::printf("obstacle layer: free ground flagged %.2f %% of %d cells; ghosts %.1f %% of %d cells movers left and a later "
                    "frame saw; static footprints: %.1f %% of the %d cells with a value marked, %.1f %% of the %d in view\n",
                    pct(dm.obs_free_flagged, dm.obs_free_known), dm.obs_free_known, pct(dm.obs_path_ghost, dm.obs_path_seen),
                    dm.obs_path_seen, pct(dm.obs_static_marked, dm.obs_static_known), dm.obs_static_known,
                    pct(dm.obs_static_in_view_marked, dm.obs_static_in_view), dm.obs_static_in_view);
      }
    }
    std::ofstream(report) << y.str();
    std::printf("wrote %s\n", report.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sgd_evaluate: %s\n", e.what());
    return 1;
  }
  return 0;
}
