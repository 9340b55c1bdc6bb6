#include "stereo_ground_dem/sim/SceneOptions.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "stereo_ground_dem/sim/ScenePreset.hpp"

namespace stereo_ground_dem::sim {

namespace {

struct KindName {
  SceneKind kind;
  const char* name;
};
const KindName kKindNames[] = {
    {SceneKind::kFlatRoad, "flat"},       {SceneKind::kBumpAndCurb, "bump"},
    {SceneKind::kOffRoad, "offroad"},     {SceneKind::kCrest, "crest"},
    {SceneKind::kSag, "sag"},             {SceneKind::kBankedCurve, "banked_curve"},
    {SceneKind::kBounce, "bounce"},       {SceneKind::kTightCurve, "tight_curve"},
    {SceneKind::kRamp, "ramp"},           {SceneKind::kRolling, "rolling"},
    {SceneKind::kShadows, "shadows"},     {SceneKind::kTraffic, "traffic"},
};

}  // namespace

const char* sceneKindName(SceneKind kind) {
  for (const auto& k : kKindNames) {
    if (k.kind == kind) return k.name;
  }
  return "?";
}

bool sceneKindFromName(const std::string& name, SceneKind* kind) {
  for (const auto& k : kKindNames) {
    if (name == k.name) {
      *kind = k.kind;
      return true;
    }
  }
  if (name == "flat_road") {
    *kind = SceneKind::kFlatRoad;
  } else if (name == "bump_and_curb") {
    *kind = SceneKind::kBumpAndCurb;
  } else if (name == "off_road") {
    *kind = SceneKind::kOffRoad;
  } else {
    return false;
  }
  return true;
}

std::vector<SceneKind> allSceneKinds() {
  std::vector<SceneKind> v;
  for (const auto& k : kKindNames) v.push_back(k.kind);
  return v;
}

bool sceneKindIsOffRoad(SceneKind kind) {
  return kind == SceneKind::kOffRoad || kind == SceneKind::kRolling || kind == SceneKind::kBounce;
}

SceneOptions SceneOptions::standard(SceneKind kind, uint64_t seed) {
  return ScenePreset::forKind(kind, seed).scene;
}

void SceneOptions::addStandardObstacles() {
  auto box = [](double x, double y, double yaw, double l, double w, double h, double vx) {
    BoxObstacle b;
    b.center_xy = {x, y};
    b.yaw_rad = yaw;
    b.length_m = l;
    b.width_m = w;
    b.height_m = h;
    b.velocity_xy = {vx, 0.0};
    return b;
  };
  auto pole = [](double x, double y, double r, double h) {
    PoleObstacle p;
    p.xy = {x, y};
    p.radius_m = r;
    p.height_m = h;
    return p;
  };
  const size_t first_box = boxes.size(), first_pole = poles.size();
  if (offRoad()) {
    boxes.push_back(box(24.0, -3.2, 0.15, 4.4, 1.9, 1.7, 0.0));   // parked vehicle
    boxes.push_back(box(32.0, 2.0, 0.0, 4.2, 1.8, 1.5, 5.0));     // vehicle ahead, 5 m/s
    boxes.push_back(box(30.0, -5.2, 0.05, 5.0, 0.25, 1.0, 0.0));  // wall at the embankment foot
    poles.push_back(pole(15.0, 2.4, 0.15, 2.5));
    poles.push_back(pole(40.0, -4.5, 0.12, 3.0));
  } else {
    boxes.push_back(box(22.0, -2.6, 0.0, 4.2, 1.8, 1.5, 0.0));    // parked car
    boxes.push_back(box(30.0, 2.0, 0.0, 4.2, 1.8, 1.5, 5.0));     // car ahead, 5 m/s
    boxes.push_back(box(28.0, 6.0, 0.0, 6.0, 0.2, 1.2, 0.0));     // wall
    poles.push_back(pole(15.0, 5.0, 0.12, 4.0));
    poles.push_back(pole(40.0, -5.5, 0.10, 3.5));
  }
  if (!road_path.empty()) {
    // (x, y) of the set above are (arc length, offset) along the road path.
    const RoadPath path(road_path);
    for (size_t i = first_box; i < boxes.size(); ++i) {
      BoxObstacle& b = boxes[i];
      const RoadPath::Pose pose = path.poseAt(b.center_xy.x());
      const double speed = b.velocity_xy.x();
      b.center_xy = pose.xy + b.center_xy.y() * pose.normal();
      b.yaw_rad += pose.heading_rad;
      b.velocity_xy = speed * pose.tangent();
    }
    for (size_t j = first_pole; j < poles.size(); ++j) {
      PoleObstacle& p = poles[j];
      const RoadPath::Pose pose = path.poseAt(p.xy.x());
      p.xy = pose.xy + p.xy.y() * pose.normal();
    }
  }
}

bool SceneOptions::isValid(std::string* why) const {
  auto bad = [why](const std::string& msg) {
    if (why) *why = msg;
    return false;
  };
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  auto nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!positive(road_width_m) || !positive(edge_line_width_m) || !nonneg(edge_line_inset_m) ||
      !positive(centre_line_width_m) || !positive(centre_dash_length_m) ||
      !nonneg(centre_gap_length_m) || !nonneg(shoulder_width_m) ||
      !std::isfinite(road_center_y_m) || !std::isfinite(centre_dash_phase_m)) {
    return bad("road widths and dash lengths must be positive (gaps, inset, shoulder >= 0)");
  }
  if (edge_line_inset_m + edge_line_width_m > 0.5 * road_width_m) {
    return bad("edge lines do not fit on the road");
  }
  if (bump_enabled && (!positive(bump_length_m) || !nonneg(bump_height_m) ||
                       !std::isfinite(bump_center_x_m) || !(bump_y_max_m > bump_y_min_m) ||
                       !nonneg(bump_end_taper_m))) {
    return bad("bump: length > 0, height >= 0, bump_y_max_m > bump_y_min_m, taper >= 0");
  }
  if (curb_enabled && (!std::isfinite(curb_y_m) || !std::isfinite(curb_height_m))) {
    return bad("curb position and height must be finite");
  }
  if (rolling_enabled &&
      (!nonneg(rolling_amplitude_m) || !positive(rolling_min_wavelength_m) ||
       !(rolling_max_wavelength_m >= rolling_min_wavelength_m) || rolling_components < 1 ||
       rolling_components > 32)) {
    return bad("rolling terrain: amplitude >= 0, 0 < min <= max wavelength, 1..32 components");
  }
  if (ruts_enabled && (!nonneg(rut_depth_m) || !positive(rut_width_m) ||
                       !std::isfinite(rut_offset_y_m) || rut_width_m > 2.0 * std::abs(rut_offset_y_m))) {
    return bad("ruts: depth >= 0, width > 0 and the two ruts must not overlap");
  }
  if (terrace_enabled && (!std::isfinite(terrace_x_min_m) || !std::isfinite(terrace_y_min_m) ||
                          !std::isfinite(terrace_height_m))) {
    return bad("terrace parameters must be finite");
  }
  if (embankment_enabled &&
      (!std::isfinite(embankment_y_m) || !positive(embankment_height_m) ||
       !(embankment_slope_rad > 0.0 && embankment_slope_rad < 80.0 * M_PI / 180.0))) {
    return bad("embankment: height > 0 and slope in (0, 80) degrees");
  }
  if (!(sun_elevation_rad > 0.0 && sun_elevation_rad <= 0.5 * M_PI) ||
      !std::isfinite(sun_azimuth_rad) || !(ambient >= 0.0 && ambient <= 1.0)) {
    return bad("sun elevation in (0, pi/2], ambient in [0, 1]");
  }
  if (!(texture_contrast >= 0.0 && texture_contrast <= 4.0)) {
    return bad("texture_contrast must be in [0, 4]");
  }
  std::string path_why;
  if (!road_path.isValid(&path_why)) return bad(path_why);
  if (gore_enabled &&
      (road_path.empty() || !std::isfinite(gore_start_s_m) || !(gore_end_s_m > gore_start_s_m) ||
       !nonneg(gore_start_width_m) || !nonneg(gore_end_width_m) || !positive(gore_lane_width_m) ||
       !positive(hatch_width_m) || !(hatch_period_m > hatch_width_m) ||
       !std::isfinite(hatch_period_m))) {
    return bad("gore: needs a road path, end after start, widths >= 0, lane width > 0, "
               "0 < hatch width < hatch period");
  }
  for (size_t i = 0; i < profile_curves.size(); ++i) {
    const VerticalCurve& c = profile_curves[i];
    if (!std::isfinite(c.start_x_m) || !positive(c.length_m) || !(std::abs(c.grade_after) < 0.5)) {
      return bad("profile: finite starts, lengths > 0, |grade| < 0.5");
    }
    if (i > 0 && c.start_x_m < profile_curves[i - 1].start_x_m + profile_curves[i - 1].length_m) {
      return bad("profile: vertical curves sorted along x and not overlapping");
    }
  }
  if (!profile_curves.empty() && profile_curves.back().grade_after != 0.0) {
    return bad("profile: the grade after the last vertical curve must be 0");
  }
  if (bank_enabled &&
      (!bank_center_xy_m.allFinite() || !nonneg(bank_half_width_m) || !positive(bank_transition_m) ||
       !(bank_radius_m > bank_half_width_m + bank_transition_m) || !std::isfinite(bank_radius_m) ||
       !(std::abs(bank_superelevation) < 0.3))) {
    return bad("banking: radius > half width + transition, transition > 0, |superelevation| < 0.3");
  }
  std::vector<std::pair<double, double>> rows;
  for (const auto& w : transverse_waves) {
    if (!std::isfinite(w.start_x_m) || !positive(w.period_m) || w.count < 1 || w.count > 10000 ||
        !std::isfinite(w.height_m) || !(std::abs(w.height_m) < w.period_m)) {
      return bad("transverse waves: finite start, period > 0, 1..10000 waves, |height| < period");
    }
    rows.emplace_back(w.start_x_m, w.start_x_m + w.count * w.period_m);
  }
  std::sort(rows.begin(), rows.end());
  for (size_t i = 1; i < rows.size(); ++i) {
    if (rows[i].first < rows[i - 1].second) return bad("transverse wave rows must not overlap");
  }
  if (potholes.size() > 32) return bad("at most 32 potholes");
  for (const auto& h : potholes) {
    if (!h.center_xy.allFinite() || !positive(h.length_x_m) || !positive(h.width_y_m) ||
        !std::isfinite(h.depth_m)) {
      return bad("pothole: finite centre and depth, positive size");
    }
  }
  if (2 * (profile_curves.size() + transverse_waves.size()) + 4 * potholes.size() > 120) {
    return bad("too many terrain features (feature lines)");
  }
  for (const auto& b : boxes) {
    if (!b.center_xy.allFinite() || !b.velocity_xy.allFinite() || !std::isfinite(b.yaw_rad) ||
        !positive(b.length_m) || !positive(b.width_m) || !positive(b.height_m)) {
      return bad("box obstacle: finite pose and velocity, positive size");
    }
  }
  for (const auto& p : poles) {
    if (!p.xy.allFinite() || !positive(p.radius_m) || !positive(p.height_m)) {
      return bad("pole obstacle: finite position, positive radius and height");
    }
  }
  return true;
}

}  // namespace stereo_ground_dem::sim
