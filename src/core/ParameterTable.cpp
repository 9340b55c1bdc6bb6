#include "stereo_ground_dem/ParameterTable.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <fstream>
#include <sstream>
#include <opencv2/core/persistence.hpp>
#include <stdexcept>

namespace stereo_ground_dem {

bool PipelineOptions::isValid(std::string* why) const {
  std::string w;
  if (!estimator.isValid(&w)) {
    if (why) *why = w;
    return false;
  }
  if (!traversability.isValid(&w)) {
    if (why) *why = "traversability: " + w;
    return false;
  }
  if (!input.isValid(&w)) {
    if (why) *why = "input: " + w;
    return false;
  }
  if (!ortho.isValid(&w)) {
    if (why) *why = "ortho: " + w;
    return false;
  }
  if (!residual.isValid(&w)) {
    if (why) *why = "residual: " + w;
    return false;
  }
  if (!attitude.isValid(&w)) {
    if (why) *why = "attitude: " + w;
    return false;
  }
  return true;
}

ParameterTable::ParameterTable(PipelineOptions* o) {
  auto d = [this](const char* n, double* f, const char* desc, bool tunable = false) {
    entries_.push_back({n, Type::kDouble, f, desc, tunable});
  };
  auto i = [this](const char* n, int* f, const char* desc, bool tunable = false) {
    entries_.push_back({n, Type::kInt, f, desc, tunable});
  };
  auto b = [this](const char* n, bool* f, const char* desc, bool tunable = false) {
    entries_.push_back({n, Type::kBool, f, desc, tunable});
  };
  IncrementalEstimatorOptions& e = o->estimator;
  StereoEstimatorOptions& s = e.stereo;
  SurfaceAlignerOptions& a = s.aligner;
  ObstacleDetectorOptions& ob = s.obstacles;
  TraversabilityOptions& t = o->traversability;
  GreyConverterOptions& in = o->input;
  // image input
  i("image_bit_depth", &in.image_bit_depth, "significant bits of 16-bit images (12: 0..4095), 0 detect from the first image [bit]");
  // mesh and working range
  d("grid_resolution_m", &s.grid_resolution_m, "finest mesh spacing [m]");
  i("mesh_levels", &s.mesh_levels, "hierarchical meshing levels (spacing 2^(L-1) s ... s), each with one pyramid level");
  d("min_range_m", &s.min_range_m, "nearest vertices estimated, camera depth [m]", true);
  d("max_range_m", &s.max_range_m, "farthest vertices estimated, camera depth [m]", true);
  d("max_lateral_m", &s.max_lateral_m, "widest vertices estimated, |x| in the camera frame [m]", true);
  // start-up
  d("nominal_height_m", &s.nominal_height_m, "camera height above the ground, start-up guess [m]");
  d("nominal_pitch_down_rad", &s.nominal_pitch_down_rad, "camera pitch, start-up guess, positive down [rad]");
  d("nominal_roll_rad", &s.nominal_roll_rad, "camera roll, start-up guess [rad]");
  d("nominal_max_tilt_rad", &s.nominal_max_tilt_rad,
    "the start-up (and a relocalization's) ground plane of the sparse matches is tilted at most this from the ground the nominal attitude expects: not a slope beside the track (0: the plane fit's own, wider bound around the camera's axis) [rad]");
  d("plane_fit_min_range_m", &s.plane_fit_min_range_m, "start-up plane fitted on ground from [m]");
  d("plane_fit_max_range_m", &s.plane_fit_max_range_m, "start-up plane fitted on ground up to [m]");
  // cost terms
  d("smoothness_weight", &a.smoothness_weight, "lambda_s, weight of the integrated squared curvature [m^2]", true);
  d("smoothness_robust_scale_m", &a.smoothness_robust_scale_m, "Cauchy scale of second differences, <= 0 quadratic [m]", true);
  d("update_weight", &s.update_weight, "update constraint mu at 0 m depth [1/m^2]", true);
  d("update_reference_depth_m", &s.update_reference_depth_m, "mu grows as (1 + (depth/this)^2) [m]", true);
  b("use_hierarchy", &s.use_hierarchy, "coarse-to-fine meshes (false: finest mesh at every level)");
  b("model_rectification", &s.model_rectification,
    "model the pair's residual vertical misalignment, measured by sparse matches", true);
  d("robust_scale_grey", &a.robust_scale_grey, "Cauchy scale of the photometric residual, <= 0 least squares [grey]", true);
  d("image_noise_std_grey", &a.image_noise_std_grey, "photometric noise sigma, sets the chi^2 scale [grey]", true);
  d("presmooth_sigma_px", &s.presmooth_sigma_px, "Gaussian blur of full-resolution images [px]");
  d("stereo_presmooth_sigma_px", &s.stereo_presmooth_sigma_px,
    "... of one-pair runs (dem_offline --left --right) [px]");
  i("iterations_per_level", &e.iterations_per_level, "Gauss-Newton iterations per coarse level, incremental mode", true);
  i("fine_iterations", &e.fine_iterations, "Gauss-Newton iterations at pyramid levels 0 and 1, incremental mode", true);
  i("stereo_fine_iterations", &e.stereo_fine_iterations,
    "... at the fine levels without the temporal pairs (level 0 at KITTI resolution; 0: fine_iterations)", true);
  i("repeat_iterations", &e.repeat_iterations,
    "... of the finest temporal level's second run, after the moving-texture test (0: fine_iterations)", true);
  i("stereo_iterations_per_level", &s.iterations_per_level, "Gauss-Newton iterations per level, stereo mode", true);
  i("tracking_levels", &e.tracking_levels, "mesh/pyramid levels used for each tracked frame (<= mesh_levels)", true);
  i("temporal_finest_level", &e.temporal_finest_level, "finest pyramid level of the temporal pairs and motion", true);
  i("min_temporal_width_px", &e.min_temporal_width_px, "... finer where that level is narrower than this [px]", true);
  i("num_threads", &a.num_threads, "threads of the pixel loop");
  d("cg_tolerance", &a.cg_tolerance, "relative residual at which the conjugate-gradient solves of a step stop");
  b("use_map_prior", &e.use_map_prior, "tie vertices to their fused map values (C_P)", true);
  d("prior_weight", &e.prior_weight, "scale of the map information in C_P", true);
  d("dark_level_grey", &a.dark_level_grey, "pixels at or below are not used [grey]", true);
  d("saturated_level_grey", &a.saturated_level_grey, "pixels at or above are not used [grey]", true);
  d("textured_gradient_grey_per_px", &a.textured_gradient_grey_per_px,
    "a vertex needs min_ground_pixels pixels with at least this gradient to be observed [grey/px]", true);
  // obstacles
  b("obstacles_enabled", &ob.enabled, "occlusion reasoning: exclude obstacle pixels from the ground", true);
  i("obstacle_level", &ob.level, "pyramid level of the obstacle test");
  d("min_obstacle_height_m", &ob.min_obstacle_height_m, "upright surfaces at least this high are obstacles [m]", true);
  d("obstacle_cost_ratio", &ob.cost_ratio, "obstacle when its photometric cost < ratio * ground's", true);
  d("hidden_pixel_ratio", &s.hidden_pixel_ratio, "vertex hidden by an obstacle when obstacle pixels > ratio * ground pixels", true);
  i("min_ground_pixels", &s.min_ground_pixels, "vertices with fewer ground pixels are not observed", true);
  d("min_incidence_ratio", &s.min_incidence_ratio,
    "a vertex seen more obliquely than this fraction of level ground's incidence is not observed (0: off; `SurfaceIncidence`)", true);
  d("ground_band_m", &ob.ground_band_m, "ground raised or lowered by up to this is still ground [m]", true);
  d("far_depth_ratio", &ob.far_depth_ratio,
    "pixels a surface this many times farther than the ground explains better see past the mesh: excluded, no obstacle (0: off)", true);
  b("far_ground_seeds", &e.far_seeds.enabled,
    "unknown vertices under ground seen past the surface (a crest's far side) start at its rough points, vertices standing above those pixels' rays at the ray; then the obstacle test runs again (`FarGroundSeedsOptions`)", true);
  b("rising_ground_seeds", &e.rising_seeds.enabled,
    "vertices under ground rising out of the surface (an embankment the upright test flagged) start at its points where they lie on one height per vertex and grow from the surface's ground not too steeply; then the obstacle test runs again (`RisingGroundSeedsOptions`)", true);
  d("hidden_body_depth_m", &ob.hidden_body_depth_m, "hidden ground this close to an obstacle is its body, farther its shadow (unknown) [m]", true);
  b("hidden_body_along_ray", &ob.hidden_body_along_ray,
    "... only behind the obstacle along the camera's rays (fewer marks on free ground, fewer obstacle cells found)", true);
  b("obstacle_foot_depth", &ob.foot_depth, "an obstacle stands at the ground below its lowest pixel: its depth from there");
  b("obstacle_continue_at_left_border", &ob.continue_at_left_border,
    "an obstacle reaching the left limit of the test (what the right image cannot see) over two windows' rows continues to the border");
  // failure handling and input checks
  d("max_speed_m_per_s", &e.check.max_speed_m_per_s, "faster estimated motion is a failure [m/s]", true);
  d("max_turn_rate_rad_per_s", &e.check.max_turn_rate_rad_per_s, "faster estimated rotation is a failure [rad/s]", true);
  d("max_height_jump_m", &e.check.max_height_jump_m, "well-known vertices moving this far are implausible [m]", true);
  d("max_jump_fraction", &e.check.max_jump_fraction, "... for more than this fraction of them", true);
  d("min_observed_fraction", &e.check.min_observed_fraction,
    "fewer ground vertices observed than this fraction of the usual number: the ground support collapsed, failure", true);
  i("reinit_after_failures", &e.reinit_after_failures, "consecutive failures before re-initialization", true);
  b("relocalize_against_map", &e.relocalize_against_map,
    "at re-initialization, track the frame from the stereo pair's attitude against the map and the last tracked images first (the map gives heading and position); the stereo pair's surface is fused only when that fails", true);
  i("prealign_level", &e.prealign_level, "pyramid level of the motion-only pre-alignment", true);
  b("temporal_checkerboard", &e.temporal_checkerboard, "temporal pairs use every other pixel (faster)", true);
  b("exclude_previous_obstacles", &e.exclude_previous_obstacles,
    "temporal pairs skip samples on the previous frame's obstacle pixels", true);
  b("carry_moving_texture", &e.carry_moving_texture,
    "temporal pairs skip the texture flagged as moving at the same pixels in the last two frames (it moves with the vehicle: a car ahead's shadow) from the start of the frame, pre-alignment included; needs `temporal_consistency`", true);
  b("repeat_from_prediction", &e.repeat_from_prediction,
    "the finest temporal level's second pass (after the moving-texture test took texture out of the temporal pairs) starts from the prediction when its cost per sample is below `hypothesis_win_ratio` times the first pass's pose's: that pose was pulled by the texture (a car ahead and its shadow)", true);
  b("temporal_visibility", &e.temporal_visibility.enabled,
    "temporal pairs skip ground the previous camera did not see (hidden by the surface itself)", true);
  d("temporal_visibility_tolerance", &e.temporal_visibility.inverse_depth_tolerance,
    "hidden when the previous view's surface there is nearer by more than this share of the inverse depth", true);
  b("skyline_mask", &e.skyline.enabled,
    "temporal pairs skip the ground's outline against a blank background (sky, glare): an occluding contour, it moves with the viewpoint, not with the ground (`SkylineMaskOptions`)", true);
  d("skyline_blank_gradient_grey_per_px", &e.skyline.blank_gradient_grey_per_px,
    "... blank: mean image gradient over a 9 px box below this (a rendered sky's noise ~0.6, ground 3-9) [grey/px]", true);
  b("use_cross_temporal_pair", &e.use_cross_temporal_pair,
    "also align with the previous right image (ties motion to the stereo calibration)", true);
  d("motion_search_min_m", &e.motion_search_min_m, "search without a velocity: shortest step per frame period [m]", true);
  d("motion_search_max_m", &e.motion_search_max_m, "... longest step per frame period [m]", true);
  d("motion_search_step_m", &e.motion_search_step_m, "... step of the search per frame period [m]", true);
  d("motion_search_max_reverse_m", &e.motion_search_max_reverse_m, "... never more backwards than this [m]", true);
  d("rotation_hypothesis_rad", &e.rotation_hypothesis_rad, "attitude step of the rotation hypotheses [rad]", true);
  d("hypothesis_accept_ratio", &e.hypothesis_accept_ratio,
    "a start is good enough below this times the usual pre-alignment cost", true);
  d("hypothesis_win_ratio", &e.hypothesis_win_ratio,
    "with a velocity, another start replaces the prediction only below this times its cost (and the prediction replaces the pose of the pass before repeat_from_prediction's second pass only below this times that pose's)", true);
  d("max_init_std_m", &e.max_init_std_m, "map heights less certain start from the extended surface [m]", true);
  d("motion_max_depth_m", &e.motion_max_depth_m, "levels estimating the motion use vertices up to this depth (0: all) [m]", true);
  i("final_undamped_step", &e.final_undamped_step, "almost undamped last step: 0 none, 1 finest level, 2 fine levels", true);
  i("search_candidates", &e.search_candidates, "search poses aligned when the velocity is unknown", true);
  i("prealign_iterations", &e.prealign_iterations, "iterations of the motion-only pre-alignment (0: none)", true);
  i("prealign_screen_iterations", &e.prealign_screen_iterations,
    "... of the rotation/scale hypotheses, the winner then gets the rest (0: all get all)", true);
  d("max_acceleration_mps2", &e.max_acceleration_mps2,
    "a pre-alignment moving the camera more than this times the gap squared from the prediction is not trusted: the prediction's own is rejected (the joint levels start from the prediction), another start's is no candidate (0: no bound) [m/s^2]", true);
  i("prealign_refine_iterations", &e.prealign_refine_iterations, "then iterations one pyramid level finer when the motion was not the predicted one (0: never)", true);
  d("max_residual_ratio", &e.check.max_residual_ratio, "median residual above this times the usual: failure", true);
  d("max_residual_increase_grey", &e.check.max_residual_increase_grey, "... and above the usual plus this [grey]", true);
  d("nominal_frame_period_s", &e.nominal_frame_period_s, "frame period used when stamps do not increase [s]");
  d("min_mean_grey", &e.min_mean_grey, "darker images are rejected [grey]", true);
  d("max_saturated_fraction", &e.max_saturated_fraction, "images with more saturated pixels are rejected", true);
  d("min_std_grey", &e.min_std_grey, "images with less contrast are rejected [grey]", true);
  // map
  d("map_keep_radius_m", &e.map.keep_radius_m, "map tiles farther from the vehicle are evicted [m]", true);
  i("map_tile_size", &e.map.tile_size, "vertices per map tile side");
  d("map_max_information", &e.map.max_information, "cap on a vertex's information [1/m^2]", true);
  d("map_obstacle_hit", &e.map.obstacle_hit,
    "obstacle score a frame's evidence adds (a vertex is an obstacle from 1; 0.6: two frames' evidence)");
  // traversability
  d("critical_slope_rad", &t.critical_slope_rad, "slope giving traversability 0 [rad]", true);
  d("critical_step_m", &t.critical_step_m, "step height giving traversability 0 [m]", true);
  d("critical_roughness_m", &t.critical_roughness_m, "roughness giving traversability 0 [m]", true);
  d("slope_window_radius_m", &t.slope_window_radius_m, "half side of the slope plane-fit window [m]", true);
  d("step_window_radius_m", &t.step_window_radius_m, "half side of the robot-sized step window [m]", true);
  d("step_run_m", &t.step_run_m, "horizontal run over which a rise counts as a step [m]", true);
  d("roughness_window_radius_m", &t.roughness_window_radius_m, "half side of the roughness window [m]", true);
  d("height_std_floor_m", &t.height_std_floor_m, "floor on the heights' std in the traversability_confidence layer [m]");
  // ortho-texture
  b("ortho_enabled", &o->ortho.enabled, "drape the left images onto the map (intensity layer, ortho.tif / ortho.png)");
  d("ortho_resolution_m", &o->ortho.resolution_m, "texel size of the ortho-texture [m]");
  d("ortho_max_range_m", &o->ortho.max_range_m, "image pixels deeper than this (along the optical axis) are not draped [m]");
  // photometric residual
  b("residual_enabled", &o->residual.enabled, "per-cell photometric residual and outlier rate layers");
  d("residual_update_weight", &o->residual.update_weight, "weight of the newest frame in the residual layers' moving averages (0..1]");
  d("residual_outlier_sigmas", &o->residual.outlier_sigmas, "a cell is an outlier when its residual exceeds this many robust sigmas of the frame's cells");
  d("residual_min_outlier_grey", &o->residual.min_outlier_grey, "... and this many grey levels [grey]");
  d("residual_max_published_outlier_rate", &o->residual.max_published_outlier_rate,
    "heights of cells whose outlier rate (obstacle pixels and moving texture not counted) is at or above this are published as unknown: the images keep contradicting them (ground a guardrail hides); > 1: all published (needs residual_enabled)");
  // the camera above the local ground
  d("attitude_radius_m", &o->attitude.radius_m, "ground attitude: map vertices within this distance of the camera's nadir [m]");
  d("attitude_min_coverage", &o->attitude.min_coverage, "ground attitude: fraction of that disc that must be known [-]");
  d("attitude_mount_height_tolerance_m", &o->attitude.mount_height_tolerance_m,
    "mount warning: typical height above the ground may move this much from the map's start [m]");
  d("attitude_mount_angle_tolerance_rad", &o->attitude.mount_angle_tolerance_rad,
    "mount warning: ... and pitch or roll this much [rad]");
  i("attitude_mount_window_frames", &o->attitude.mount_window_frames, "mount warning: frames whose medians are compared");
}

namespace {
/// `s` cut to `max_chars` with control characters replaced, for one-line messages.
std::string printable(const std::string& s, size_t max_chars = 40) {
  std::string out = s.substr(0, max_chars);
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 32 || c == 127) c = '?';
  return s.size() > max_chars ? out + "..." : out;
}
}  // namespace

const ParameterTable::Entry* ParameterTable::find(const std::string& name) const {
  for (const auto& e : entries_)
    if (e.name == name) return &e;
  return nullptr;
}

std::string ParameterTable::whyNotSettable(const std::string& name, double value) const {
  const Entry* e = find(name);
  if (!e) return "unknown parameter '" + name + "'";
  std::ostringstream os;
  os << "'" << name << "' ";
  if (!std::isfinite(value)) {
    os << "must be a finite number, got " << (std::isnan(value) ? "nan" : value > 0 ? "inf" : "-inf");
    return os.str();
  }
  switch (e->type) {
    case Type::kDouble: return {};
    case Type::kInt:
      if (value != std::floor(value)) {
        os << "must be an integer, got " << value;
        return os.str();
      }
      if (value < std::numeric_limits<int>::min() || value > std::numeric_limits<int>::max()) {
        os << "= " << value << " is outside the integer range";
        return os.str();
      }
      return {};
    case Type::kBool:
      if (value != 0.0 && value != 1.0) {
        os << "must be true or false (or 1 or 0), got " << value;
        return os.str();
      }
      return {};
  }
  return "unknown parameter type";
}

bool ParameterTable::set(const std::string& name, double value) const {
  if (!whyNotSettable(name, value).empty()) return false;
  const Entry* e = find(name);
  switch (e->type) {
    case Type::kDouble: *static_cast<double*>(e->field) = value; return true;
    case Type::kInt: *static_cast<int*>(e->field) = static_cast<int>(value); return true;
    case Type::kBool: *static_cast<bool*>(e->field) = value != 0.0; return true;
  }
  return false;
}

double ParameterTable::get(const Entry& e) const {
  switch (e.type) {
    case Type::kDouble: return *static_cast<const double*>(e.field);
    case Type::kInt: return *static_cast<const int*>(e.field);
    case Type::kBool: return *static_cast<const bool*>(e.field) ? 1.0 : 0.0;
  }
  return 0.0;
}

PipelineOptions ParameterTable::load(const std::string& path) {
  PipelineOptions o;
  if (!path.empty()) ParameterTable(&o).loadYaml(path);
  std::string why;
  if (!o.isValid(&why)) throw std::runtime_error("invalid parameters: " + why);
  return o;
}

void ParameterTable::loadYaml(const std::string& path) const {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("parameter file '" + path + "': cannot be opened");
  std::stringstream text;
  text << in.rdbuf();
  std::string content = text.str();
  // OpenCV's YAML reader insists on a "%YAML:1.0" first line; plain YAML files do not have it.
  if (content.rfind("%YAML", 0) != 0) content = "%YAML:1.0\n" + content;
  if (content.find_first_not_of(" \t\r\n", content.find('\n') + 1) == std::string::npos) return;  // empty file
  cv::FileStorage fs;
  try {
    fs.open(content, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& ex) {
    throw std::runtime_error("parameter file '" + path + "': not readable YAML (" + printable(ex.err, 200) + ")");
  }
  if (!fs.isOpened()) throw std::runtime_error("parameter file '" + path + "': not readable YAML");
  cv::FileNode root = fs.root();
  if (root.empty() || root.isNone()) return;  // comments only
  if (!root.isMap()) throw std::runtime_error("parameter file '" + path + "': the top level is not a map of name: value");
  for (const char* wrapper : {"stereo_ground_dem", "dem_nodelet"}) {
    if (!root[wrapper].empty() && root[wrapper].isMap()) root = root[wrapper];
  }
  for (cv::FileNodeIterator it = root.begin(); it != root.end(); ++it) {
    const cv::FileNode node = *it;
    const std::string name = printable(node.name());
    const Entry* e = find(name);
    if (!e) {
      // topic and frame names belong to the ROS layer; they may live in the same file
      static const char* kRosOnly[] = {"left_topic", "right_topic", "queue_size", "approximate_sync",
                                       "odom_frame", "base_frame", "map_frame", "camera_frame",
                                       "publish_tf", "publish_rate_hz", "occupancy_unknown_below", "slop_s"};
      bool ros_only = false;
      for (const char* r : kRosOnly) ros_only = ros_only || name == r;
      if (ros_only) continue;
      throw std::runtime_error("parameter file '" + path + "': unknown parameter '" + name + "'");
    }
    const std::string where = "parameter file '" + path + "': ";
    double value = 0.0;
    if (node.isInt() || node.isReal()) {
      value = static_cast<double>(node);
    } else if (node.isString()) {
      const std::string v = static_cast<std::string>(node);
      std::string lower = v;
      for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      const bool is_true = v == "true" || v == "True" || v == "TRUE";
      const bool is_false = v == "false" || v == "False" || v == "FALSE";
      char* end = nullptr;
      const double number = std::strtod(v.c_str(), &end);
      const bool numeric = !v.empty() && end != v.c_str() && *end == '\0';
      if (lower == ".nan") {  // YAML's spellings of the non-finite floats
        value = std::numeric_limits<double>::quiet_NaN();
      } else if (lower == ".inf" || lower == "+.inf" || lower == "-.inf") {
        value = lower[0] == '-' ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
      } else if (is_true || is_false) {
        if (e->type != Type::kBool) throw std::runtime_error(where + "'" + name + "' must be a number, got '" + v + "'");
        value = is_true ? 1.0 : 0.0;
      } else if (numeric) {
        value = number;  // e.g. "nan", "inf": refused below with the number
      } else {
        throw std::runtime_error(where + "'" + name + "' is not a number: '" + printable(v) + "'");
      }
    } else {
      throw std::runtime_error(where + "'" + name + "' must be a single number, not " +
                               (node.isMap() ? "a map" : node.isSeq() ? "a list" : "empty"));
    }
    const std::string why = whyNotSettable(name, value);
    if (!why.empty()) throw std::runtime_error(where + why);
    set(name, value);
  }
}

}  // namespace stereo_ground_dem
