#include "stereo_ground_dem/sim/SceneOptions.hpp"

#include <cmath>
#include <string>

namespace stereo_ground_dem::sim {

const char* sceneKindName(SceneKind kind) {
  switch (kind) {
    case SceneKind::kFlatRoad: return "flat";
    case SceneKind::kBumpAndCurb: return "bump";
    case SceneKind::kOffRoad: return "offroad";
  }
  return "?";
}

bool sceneKindFromName(const std::string& name, SceneKind* kind) {
  if (name == "flat" || name == "flat_road") {
    *kind = SceneKind::kFlatRoad;
  } else if (name == "bump" || name == "bump_and_curb") {
    *kind = SceneKind::kBumpAndCurb;
  } else if (name == "offroad" || name == "off_road") {
    *kind = SceneKind::kOffRoad;
  } else {
    return false;
  }
  return true;
}

SceneOptions SceneOptions::standard(SceneKind kind, uint64_t seed) {
  SceneOptions o;
  o.kind = kind;
  o.seed = seed;
  switch (kind) {
    case SceneKind::kFlatRoad:
      break;
    case SceneKind::kBumpAndCurb:
      o.bump_enabled = true;
      o.curb_enabled = true;
      break;
    case SceneKind::kOffRoad:
      o.rolling_enabled = true;
      o.ruts_enabled = true;
      o.terrace_enabled = true;
      o.embankment_enabled = true;
      break;
  }
  return o;
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
  if (kind == SceneKind::kOffRoad) {
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
