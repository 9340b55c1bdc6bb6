#pragma once
/// \file SceneOptions.hpp
/// What a SyntheticScene is made of: the scene kind (material layout), the road layout, the
/// terrain features, the lighting and the obstacles. All lengths in the ground frame G (x forward,
/// y left, z up [m]). The presets of the scene zoo (ScenePreset.hpp) fill these options.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "stereo_ground_dem/sim/RoadPath.hpp"

namespace stereo_ground_dem::sim {

/// The scene kinds: the three standard scenes and the zoo (docs/zoo.md). The kind names the scene
/// and selects its material layout: a dirt track for kOffRoad, kRolling and kBounce, a road with
/// lane paint for the others.
enum class SceneKind {
  kFlatRoad, kBumpAndCurb, kOffRoad,
  kCrest, kSag, kBankedCurve, kBounce, kTightCurve, kRamp, kRolling, kShadows, kTraffic
};

/// "flat", "bump", "offroad", "crest", "sag", "banked_curve", "bounce", "tight_curve", "ramp",
/// "rolling", "shadows", "traffic".
const char* sceneKindName(SceneKind kind);
/// Inverse of sceneKindName(); also accepts "flat_road", "bump_and_curb", "off_road".
bool sceneKindFromName(const std::string& name, SceneKind* kind);
/// Every kind, in the order of the enum.
std::vector<SceneKind> allSceneKinds();
/// Whether the kind has the off-road material layout (dirt track and grass, no paint).
bool sceneKindIsOffRoad(SceneKind kind);

/// A vertical curve of the longitudinal profile (a function of x): over [start_x_m, start_x_m +
/// length_m] the grade changes linearly (the height is a parabola) from the grade before to
/// grade_after. Between curves the grade is constant (straight grades).
struct VerticalCurve {
  double start_x_m = 0.0;   ///< [m]
  double length_m = 60.0;   ///< [m], > 0
  double grade_after = 0.0; ///< dz/dx after the curve [m/m]
};

/// A row of `count` transverse raised-cosine waves along x, across all y: height_m / 2 * (1 -
/// cos(2 pi (x - start_x_m) / period_m)) for start_x_m <= x <= start_x_m + count * period_m.
/// Speed bumps in series, a washboard, or a ditch when height_m < 0.
struct TransverseWaves {
  double start_x_m = 0.0;  ///< [m]
  double period_m = 2.7;   ///< [m], > 0
  int count = 1;           ///< >= 1
  double height_m = 0.05;  ///< crest height, < 0 for troughs [m]
};

/// A pothole: the ground sinks by depth_m * c(x) * c(y) over an axis-parallel rectangle, c the
/// raised cosine that is 1 at the centre and 0 (with zero slope) on the rectangle's edges.
struct Pothole {
  Eigen::Vector2d center_xy = Eigen::Vector2d::Zero();  ///< [m]
  double length_x_m = 1.0;  ///< extent along x [m], > 0
  double width_y_m = 1.0;   ///< extent along y [m], > 0
  double depth_m = 0.08;    ///< [m]; < 0 makes a hump
};

/// An oriented box standing on the terrain (a vehicle, a wall when thin). Its bottom is buried
/// 1 m below the terrain height at its centre, its top is height_m above that terrain height.
struct BoxObstacle {
  Eigen::Vector2d center_xy = Eigen::Vector2d::Zero();    ///< footprint centre at time 0 [m]
  double yaw_rad = 0.0;        ///< direction of the length axis, counter-clockwise from +x [rad]
  double length_m = 4.2;       ///< extent along the length axis [m]
  double width_m = 1.8;        ///< extent across [m]
  double height_m = 1.5;       ///< top above the terrain at the centre [m]
  Eigen::Vector2d velocity_xy = Eigen::Vector2d::Zero();  ///< [m/s]; zero = static
  Eigen::Vector2d centerAt(double time_s) const { return center_xy + velocity_xy * time_s; }
};

/// A vertical cylinder standing on the terrain (a pole, a tree trunk), buried like a box.
struct PoleObstacle {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  ///< axis position [m]
  double radius_m = 0.1;                         ///< [m]
  double height_m = 3.0;                         ///< top above the terrain at the axis [m]
};

struct SceneOptions {
  SceneKind kind = SceneKind::kFlatRoad;  ///< selects the material layout (road or track)
  uint64_t seed = 1;                      ///< texture, rolling terrain and obstacle looks

  // Road (road kinds): asphalt, edge lines, dashed centre line. Without a road path the road runs
  // along x at y = road_center_y_m (distance along it: x); with one (road_path.pieces not empty)
  // it follows the path, markings by arc length and signed offset from the path.
  RoadPathOptions road_path;             ///< centreline; empty: straight along x
  double road_center_y_m = 0.0;          ///< road axis without a road path [m]
  double road_width_m = 7.5;             ///< asphalt width [m]
  double edge_line_width_m = 0.15;       ///< solid edge lines [m]
  double edge_line_inset_m = 0.20;       ///< from the asphalt edge to the line's outer edge [m]
  double centre_line_width_m = 0.12;     ///< dashed centre line [m]
  double centre_dash_length_m = 3.0;     ///< [m]
  double centre_gap_length_m = 6.0;      ///< [m]
  double centre_dash_phase_m = 1.0;      ///< a dash starts at x = phase + n * (dash + gap) [m]
  double shoulder_width_m = 1.2;         ///< gravel beyond the asphalt, then grass [m]
  bool centre_line_enabled = true;       ///< the dashed centre line

  // Gore area (road path only): on the left of the road, a hatched wedge between the road and a
  // second carriageway (gore_lane_width_m of asphalt with edge and dashed lane lines) whose width
  // goes linearly from gore_start_width_m at s = gore_start_s_m to gore_end_width_m at
  // gore_end_s_m (constant before and after). Diagonal stripes (hatch_width_m every
  // hatch_period_m, measured along s) fill it, solid lines border it.
  bool gore_enabled = false;
  double gore_start_s_m = 0.0;       ///< [m]
  double gore_end_s_m = 60.0;        ///< [m], > start
  double gore_start_width_m = 6.0;   ///< [m], >= 0
  double gore_end_width_m = 0.0;     ///< [m], >= 0
  double gore_lane_width_m = 7.5;    ///< the carriageway beyond the gore [m], > 0
  double hatch_period_m = 2.5;       ///< [m]
  double hatch_width_m = 0.5;        ///< [m]

  // Longitudinal profile: vertical curves along x (sorted, not overlapping), grade 0 before the
  // first one and required 0 after the last one (so that heights stay bounded). The profile is
  // shifted so that its height at x = 0 is 0.
  std::vector<VerticalCurve> profile_curves;

  // Banking (superelevation) around a circle: with rho = |(x, y) - bank_center_xy_m| -
  // bank_radius_m (positive outwards), the ground is bank_superelevation * rho higher for |rho| <=
  // bank_half_width_m, flattens out over bank_transition_m (a parabola, C1) and stays level
  // beyond. It rises towards the outside of the curve whichever way the curve turns.
  bool bank_enabled = false;
  Eigen::Vector2d bank_center_xy_m = Eigen::Vector2d(0.0, 120.0);  ///< [m]
  double bank_radius_m = 120.0;        ///< [m], > half width + transition
  double bank_superelevation = 0.05;   ///< cross slope [m/m], |.| < 0.3
  double bank_half_width_m = 5.0;      ///< [m], >= 0
  double bank_transition_m = 4.0;      ///< [m], > 0

  std::vector<TransverseWaves> transverse_waves;  ///< rows must not overlap in x
  std::vector<Pothole> potholes;                  ///< at most 32

  // Speed bump: raised-cosine profile along x, across the road.
  bool bump_enabled = false;
  double bump_center_x_m = 13.0;   ///< [m]
  double bump_length_m = 1.8;      ///< base length along x [m]
  double bump_height_m = 0.10;     ///< peak height [m]
  double bump_y_min_m = -3.75;     ///< hard end on the right (at the curb) [m]
  double bump_y_max_m = 3.75;      ///< full height up to here on the left [m]
  double bump_end_taper_m = 0.5;   ///< raised-cosine taper beyond bump_y_max_m [m]

  // Curb: the ground at y < curb_y_m (the sidewalk) is curb_height_m higher; vertical face.
  bool curb_enabled = false;
  double curb_y_m = -3.75;         ///< [m]
  double curb_height_m = 0.12;     ///< [m]

  // Rolling terrain: `rolling_components` plane sinusoids whose directions, wavelengths (in
  // [min, max]) and phases come from the seed; each has amplitude rolling_amplitude_m /
  // sqrt(components), so the sum has the rms of one sinusoid of amplitude rolling_amplitude_m.
  // Shifted so that the height at (0, 0) is 0.
  bool rolling_enabled = false;
  double rolling_amplitude_m = 0.3;      ///< [m]
  double rolling_min_wavelength_m = 15.0;///< [m]
  double rolling_max_wavelength_m = 40.0;///< [m]
  int rolling_components = 4;

  // Wheel ruts along x: raised-cosine grooves centred at y = +-rut_offset_y_m.
  bool ruts_enabled = false;
  double rut_offset_y_m = 0.8;     ///< [m]
  double rut_depth_m = 0.06;       ///< [m]
  double rut_width_m = 0.35;       ///< [m]

  // Terrace: the region x > terrace_x_min_m and y > terrace_y_min_m is terrace_height_m higher
  // (vertical faces on both lines).
  bool terrace_enabled = false;
  double terrace_x_min_m = 18.0;   ///< [m]
  double terrace_y_min_m = 3.0;    ///< [m]
  double terrace_height_m = 0.4;   ///< [m]

  // Embankment: for y < embankment_y_m the ground rises at embankment_slope_rad up to
  // embankment_height_m, then stays level.
  bool embankment_enabled = false;
  double embankment_y_m = -6.0;              ///< foot of the slope [m]
  double embankment_slope_rad = 35.0 * M_PI / 180.0;  ///< [rad], < 80 degrees
  double embankment_height_m = 2.0;          ///< [m]

  // Lighting: Lambertian with an ambient part; level ground is not changed (factor 1).
  double sun_elevation_rad = 50.0 * M_PI / 180.0;
  double sun_azimuth_rad = 150.0 * M_PI / 180.0;  ///< counter-clockwise from +x
  double ambient = 0.45;                          ///< share of the light that is ambient, 0..1
  /// Cast shadows of the obstacles on the terrain: a terrain sample whose ray towards the sun
  /// hits an obstacle (at the sample's time) gets only the ambient share of the light.
  bool cast_shadows = false;
  /// Scales the texture (noise) amplitude of every terrain material (1: as designed; < 1: weak,
  /// low-texture surfaces). Obstacles keep theirs.
  double texture_contrast = 1.0;

  std::vector<BoxObstacle> boxes;  ///< object ids 1..boxes.size()
  std::vector<PoleObstacle> poles; ///< object ids boxes.size()+1 ..

  /// The scene of `kind` (the three standard scenes as documented in the package docs, the zoo
  /// scenes as in docs/zoo.md, with their own obstacles where they have any).
  static SceneOptions standard(SceneKind kind, uint64_t seed = 1);
  /// Adds a fixed set of obstacles suited to the scene kind: a parked car, a car driving ahead at
  /// 5 m/s, a wall and two poles, all off the driving line near y = 0 except the moving car. With
  /// a road path, (x, y) of this set are taken as (arc length, offset) along the path.
  void addStandardObstacles();
  /// Whether the material layout is the off-road one (sceneKindIsOffRoad(kind)).
  bool offRoad() const { return sceneKindIsOffRoad(kind); }

  bool isValid(std::string* why = nullptr) const;
};

}  // namespace stereo_ground_dem::sim
