#include "stereo_ground_dem/sim/SyntheticScene.hpp"

#include <opencv2/core.hpp>
#include <stdexcept>
#include <utility>

namespace stereo_ground_dem::sim {

namespace {

uint64_t parseSeed(const std::string& text, const std::string& path) {
  try {
    size_t pos = 0;
    const unsigned long long v = std::stoull(text, &pos);
    if (pos != text.size()) throw std::invalid_argument("trailing characters");
    return static_cast<uint64_t>(v);
  } catch (const std::exception&) {
    throw std::runtime_error("scene file '" + path + "': seed '" + text + "' is not an unsigned integer");
  }
}

}  // namespace

SyntheticScene::SyntheticScene(const SceneOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("SceneOptions: " + why);
  terrain_ = std::make_shared<const TerrainModel>(options_);
  caster_ = std::make_shared<const RayCaster>(terrain_, options_);
  shader_ = std::make_shared<const SurfaceShader>(options_, caster_);
}

// ------------------------------------------------------------------------------------------------
// YAML

void SyntheticScene::toYaml(const std::string& path) const {
  cv::FileStorage fs(path, cv::FileStorage::WRITE | cv::FileStorage::FORMAT_YAML);
  if (!fs.isOpened()) throw std::runtime_error("scene file '" + path + "': cannot be written");
  const SceneOptions& o = options_;
  fs << "kind" << sceneKindName(o.kind);
  fs << "seed" << std::to_string(o.seed);
  fs << "road_center_y_m" << o.road_center_y_m << "road_width_m" << o.road_width_m
     << "edge_line_width_m" << o.edge_line_width_m << "edge_line_inset_m" << o.edge_line_inset_m
     << "centre_line_width_m" << o.centre_line_width_m << "centre_dash_length_m"
     << o.centre_dash_length_m << "centre_gap_length_m" << o.centre_gap_length_m
     << "centre_dash_phase_m" << o.centre_dash_phase_m << "shoulder_width_m" << o.shoulder_width_m;
  fs << "bump_enabled" << static_cast<int>(o.bump_enabled) << "bump_center_x_m" << o.bump_center_x_m
     << "bump_length_m" << o.bump_length_m << "bump_height_m" << o.bump_height_m << "bump_y_min_m"
     << o.bump_y_min_m << "bump_y_max_m" << o.bump_y_max_m << "bump_end_taper_m"
     << o.bump_end_taper_m;
  fs << "curb_enabled" << static_cast<int>(o.curb_enabled) << "curb_y_m" << o.curb_y_m
     << "curb_height_m" << o.curb_height_m;
  fs << "rolling_enabled" << static_cast<int>(o.rolling_enabled) << "rolling_amplitude_m"
     << o.rolling_amplitude_m << "rolling_min_wavelength_m" << o.rolling_min_wavelength_m
     << "rolling_max_wavelength_m" << o.rolling_max_wavelength_m << "rolling_components"
     << o.rolling_components;
  fs << "ruts_enabled" << static_cast<int>(o.ruts_enabled) << "rut_offset_y_m" << o.rut_offset_y_m
     << "rut_depth_m" << o.rut_depth_m << "rut_width_m" << o.rut_width_m;
  fs << "terrace_enabled" << static_cast<int>(o.terrace_enabled) << "terrace_x_min_m"
     << o.terrace_x_min_m << "terrace_y_min_m" << o.terrace_y_min_m << "terrace_height_m"
     << o.terrace_height_m;
  fs << "embankment_enabled" << static_cast<int>(o.embankment_enabled) << "embankment_y_m"
     << o.embankment_y_m << "embankment_slope_rad" << o.embankment_slope_rad
     << "embankment_height_m" << o.embankment_height_m;
  fs << "sun_elevation_rad" << o.sun_elevation_rad << "sun_azimuth_rad" << o.sun_azimuth_rad
     << "ambient" << o.ambient;
  // Zoo features (optional when read: files written before them rebuild as before).
  fs << "cast_shadows" << static_cast<int>(o.cast_shadows) << "texture_contrast"
     << o.texture_contrast << "centre_line_enabled" << static_cast<int>(o.centre_line_enabled);
  fs << "road_path" << "{" << "anchor_x_m" << o.road_path.anchor_xy_m.x() << "anchor_y_m"
     << o.road_path.anchor_xy_m.y() << "anchor_heading_rad" << o.road_path.anchor_heading_rad
     << "start_s_m" << o.road_path.start_s_m << "pieces" << "[";
  for (const auto& pc : o.road_path.pieces) {
    fs << "{" << "length_m" << pc.length_m << "curvature_per_m" << pc.curvature_per_m << "}";
  }
  fs << "]" << "}";
  fs << "gore_enabled" << static_cast<int>(o.gore_enabled) << "gore_start_s_m" << o.gore_start_s_m
     << "gore_end_s_m" << o.gore_end_s_m << "gore_start_width_m" << o.gore_start_width_m
     << "gore_end_width_m" << o.gore_end_width_m << "gore_lane_width_m" << o.gore_lane_width_m
     << "hatch_period_m" << o.hatch_period_m << "hatch_width_m" << o.hatch_width_m;
  fs << "profile_curves" << "[";
  for (const auto& c : o.profile_curves) {
    fs << "{" << "start_x_m" << c.start_x_m << "length_m" << c.length_m << "grade_after"
       << c.grade_after << "}";
  }
  fs << "]";
  fs << "bank_enabled" << static_cast<int>(o.bank_enabled) << "bank_center_x_m"
     << o.bank_center_xy_m.x() << "bank_center_y_m" << o.bank_center_xy_m.y() << "bank_radius_m"
     << o.bank_radius_m << "bank_superelevation" << o.bank_superelevation << "bank_half_width_m"
     << o.bank_half_width_m << "bank_transition_m" << o.bank_transition_m;
  fs << "transverse_waves" << "[";
  for (const auto& w : o.transverse_waves) {
    fs << "{" << "start_x_m" << w.start_x_m << "period_m" << w.period_m << "count" << w.count
       << "height_m" << w.height_m << "}";
  }
  fs << "]";
  fs << "potholes" << "[";
  for (const auto& h : o.potholes) {
    fs << "{" << "center_x_m" << h.center_xy.x() << "center_y_m" << h.center_xy.y()
       << "length_x_m" << h.length_x_m << "width_y_m" << h.width_y_m << "depth_m" << h.depth_m
       << "}";
  }
  fs << "]";
  fs << "boxes" << "[";
  for (const auto& b : o.boxes) {
    fs << "{" << "center_x_m" << b.center_xy.x() << "center_y_m" << b.center_xy.y() << "yaw_rad"
       << b.yaw_rad << "length_m" << b.length_m << "width_m" << b.width_m << "height_m"
       << b.height_m << "velocity_x_m_per_s" << b.velocity_xy.x() << "velocity_y_m_per_s"
       << b.velocity_xy.y() << "}";
  }
  fs << "]";
  fs << "poles" << "[";
  for (const auto& p : o.poles) {
    fs << "{" << "x_m" << p.xy.x() << "y_m" << p.xy.y() << "radius_m" << p.radius_m << "height_m"
       << p.height_m << "}";
  }
  fs << "]";
  // Derived values, for readers that do not rebuild the scene (ignored by fromYaml).
  fs << "rolling_waves" << "[";
  for (const auto& w : terrain_->rollingWaves()) {
    fs << "{" << "kx_rad_per_m" << w.kx << "ky_rad_per_m" << w.ky << "amplitude_m" << w.amp
       << "phase_rad" << w.phase << "}";
  }
  fs << "]";
  fs << "rolling_offset_m" << terrain_->rollingOffset();
}

SceneOptions SyntheticScene::optionsFromYaml(const std::string& path) {
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("scene file '" + path + "': cannot be parsed");
  }
  if (!fs.isOpened()) throw std::runtime_error("scene file '" + path + "': cannot be opened");
  SceneOptions o;
  auto fail = [&path](const std::string& why) {
    throw std::runtime_error("scene file '" + path + "': " + why);
  };
  const auto need = [&](const char* key) {
    const cv::FileNode n = fs[key];
    if (n.empty()) fail(std::string("missing key '") + key + "'");
    return n;
  };
  auto num = [&](const char* key, double* v) {
    const cv::FileNode n = need(key);
    if (!n.isReal() && !n.isInt()) fail(std::string("'") + key + "' is not a number");
    *v = static_cast<double>(n);
  };
  auto flag = [&](const char* key, bool* v) {
    const cv::FileNode n = need(key);
    if (!n.isInt()) fail(std::string("'") + key + "' is not 0 or 1");
    *v = static_cast<int>(n) != 0;
  };
  const std::string kind = static_cast<std::string>(need("kind"));
  if (!sceneKindFromName(kind, &o.kind)) fail("unknown kind '" + kind + "'");
  const cv::FileNode seed = need("seed");
  o.seed = seed.isString() ? parseSeed(static_cast<std::string>(seed), path)
                           : static_cast<uint64_t>(static_cast<int>(seed));
  num("road_center_y_m", &o.road_center_y_m);
  num("road_width_m", &o.road_width_m);
  num("edge_line_width_m", &o.edge_line_width_m);
  num("edge_line_inset_m", &o.edge_line_inset_m);
  num("centre_line_width_m", &o.centre_line_width_m);
  num("centre_dash_length_m", &o.centre_dash_length_m);
  num("centre_gap_length_m", &o.centre_gap_length_m);
  num("centre_dash_phase_m", &o.centre_dash_phase_m);
  num("shoulder_width_m", &o.shoulder_width_m);
  flag("bump_enabled", &o.bump_enabled);
  num("bump_center_x_m", &o.bump_center_x_m);
  num("bump_length_m", &o.bump_length_m);
  num("bump_height_m", &o.bump_height_m);
  num("bump_y_min_m", &o.bump_y_min_m);
  num("bump_y_max_m", &o.bump_y_max_m);
  num("bump_end_taper_m", &o.bump_end_taper_m);
  flag("curb_enabled", &o.curb_enabled);
  num("curb_y_m", &o.curb_y_m);
  num("curb_height_m", &o.curb_height_m);
  flag("rolling_enabled", &o.rolling_enabled);
  num("rolling_amplitude_m", &o.rolling_amplitude_m);
  num("rolling_min_wavelength_m", &o.rolling_min_wavelength_m);
  num("rolling_max_wavelength_m", &o.rolling_max_wavelength_m);
  {
    const cv::FileNode n = need("rolling_components");
    if (!n.isInt()) fail("'rolling_components' is not an integer");
    o.rolling_components = static_cast<int>(n);
  }
  flag("ruts_enabled", &o.ruts_enabled);
  num("rut_offset_y_m", &o.rut_offset_y_m);
  num("rut_depth_m", &o.rut_depth_m);
  num("rut_width_m", &o.rut_width_m);
  flag("terrace_enabled", &o.terrace_enabled);
  num("terrace_x_min_m", &o.terrace_x_min_m);
  num("terrace_y_min_m", &o.terrace_y_min_m);
  num("terrace_height_m", &o.terrace_height_m);
  flag("embankment_enabled", &o.embankment_enabled);
  num("embankment_y_m", &o.embankment_y_m);
  num("embankment_slope_rad", &o.embankment_slope_rad);
  num("embankment_height_m", &o.embankment_height_m);
  num("sun_elevation_rad", &o.sun_elevation_rad);
  num("sun_azimuth_rad", &o.sun_azimuth_rad);
  num("ambient", &o.ambient);
  // Optional keys (the zoo's): absent keeps the default.
  auto optNum = [&](const char* key, double* v) {
    if (!fs[key].empty()) num(key, v);
  };
  auto optFlag = [&](const char* key, bool* v) {
    if (!fs[key].empty()) flag(key, v);
  };
  optFlag("cast_shadows", &o.cast_shadows);
  optNum("texture_contrast", &o.texture_contrast);
  optFlag("centre_line_enabled", &o.centre_line_enabled);
  optFlag("gore_enabled", &o.gore_enabled);
  optNum("gore_start_s_m", &o.gore_start_s_m);
  optNum("gore_end_s_m", &o.gore_end_s_m);
  optNum("gore_start_width_m", &o.gore_start_width_m);
  optNum("gore_end_width_m", &o.gore_end_width_m);
  optNum("gore_lane_width_m", &o.gore_lane_width_m);
  optNum("hatch_period_m", &o.hatch_period_m);
  optNum("hatch_width_m", &o.hatch_width_m);
  optFlag("bank_enabled", &o.bank_enabled);
  optNum("bank_center_x_m", &o.bank_center_xy_m.x());
  optNum("bank_center_y_m", &o.bank_center_xy_m.y());
  optNum("bank_radius_m", &o.bank_radius_m);
  optNum("bank_superelevation", &o.bank_superelevation);
  optNum("bank_half_width_m", &o.bank_half_width_m);
  optNum("bank_transition_m", &o.bank_transition_m);
  auto field = [&](const cv::FileNode& node, const char* key, const char* what) {
    const cv::FileNode n = node[key];
    if (n.empty() || (!n.isReal() && !n.isInt())) {
      fail(std::string(what) + " entry lacks the number '" + key + "'");
    }
    return static_cast<double>(n);
  };
  const cv::FileNode boxes = fs["boxes"];
  if (!boxes.empty() && !boxes.isSeq()) fail("'boxes' is not a list");
  for (const auto& n : boxes) {
    BoxObstacle b;
    b.center_xy = {field(n, "center_x_m", "box"), field(n, "center_y_m", "box")};
    b.yaw_rad = field(n, "yaw_rad", "box");
    b.length_m = field(n, "length_m", "box");
    b.width_m = field(n, "width_m", "box");
    b.height_m = field(n, "height_m", "box");
    b.velocity_xy = {field(n, "velocity_x_m_per_s", "box"), field(n, "velocity_y_m_per_s", "box")};
    o.boxes.push_back(b);
  }
  const cv::FileNode poles = fs["poles"];
  if (!poles.empty() && !poles.isSeq()) fail("'poles' is not a list");
  for (const auto& n : poles) {
    PoleObstacle p;
    p.xy = {field(n, "x_m", "pole"), field(n, "y_m", "pole")};
    p.radius_m = field(n, "radius_m", "pole");
    p.height_m = field(n, "height_m", "pole");
    o.poles.push_back(p);
  }
  auto count = [&](const cv::FileNode& node, const char* key, const char* what) {
    const cv::FileNode n = node[key];
    if (n.empty() || !n.isInt()) fail(std::string(what) + " entry lacks the integer '" + key + "'");
    return static_cast<int>(n);
  };
  auto list = [&](const char* key) {
    const cv::FileNode n = fs[key];
    if (!n.empty() && !n.isSeq()) fail(std::string("'") + key + "' is not a list");
    return n;
  };
  const cv::FileNode road = fs["road_path"];
  if (!road.empty()) {
    if (!road.isMap()) fail("'road_path' is not a map");
    o.road_path.anchor_xy_m = {field(road, "anchor_x_m", "road_path"),
                               field(road, "anchor_y_m", "road_path")};
    o.road_path.anchor_heading_rad = field(road, "anchor_heading_rad", "road_path");
    o.road_path.start_s_m = field(road, "start_s_m", "road_path");
    const cv::FileNode pieces = road["pieces"];
    if (!pieces.empty() && !pieces.isSeq()) fail("'road_path: pieces' is not a list");
    for (const auto& n : pieces) {
      RoadPiece pc;
      pc.length_m = field(n, "length_m", "road piece");
      pc.curvature_per_m = field(n, "curvature_per_m", "road piece");
      o.road_path.pieces.push_back(pc);
    }
  }
  for (const auto& n : list("profile_curves")) {
    VerticalCurve c;
    c.start_x_m = field(n, "start_x_m", "profile curve");
    c.length_m = field(n, "length_m", "profile curve");
    c.grade_after = field(n, "grade_after", "profile curve");
    o.profile_curves.push_back(c);
  }
  for (const auto& n : list("transverse_waves")) {
    TransverseWaves w;
    w.start_x_m = field(n, "start_x_m", "transverse waves");
    w.period_m = field(n, "period_m", "transverse waves");
    w.count = count(n, "count", "transverse waves");
    w.height_m = field(n, "height_m", "transverse waves");
    o.transverse_waves.push_back(w);
  }
  for (const auto& n : list("potholes")) {
    Pothole h;
    h.center_xy = {field(n, "center_x_m", "pothole"), field(n, "center_y_m", "pothole")};
    h.length_x_m = field(n, "length_x_m", "pothole");
    h.width_y_m = field(n, "width_y_m", "pothole");
    h.depth_m = field(n, "depth_m", "pothole");
    o.potholes.push_back(h);
  }
  std::string why;
  if (!o.isValid(&why)) fail(why);
  return o;
}

SyntheticScene SyntheticScene::fromYaml(const std::string& path) {
  return SyntheticScene(optionsFromYaml(path));
}

}  // namespace stereo_ground_dem::sim
