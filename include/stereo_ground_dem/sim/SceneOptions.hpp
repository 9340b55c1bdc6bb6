#pragma once
/// \file SceneOptions.hpp
/// What a SyntheticScene is made of: the scene kind (material layout), the terrain features, the
/// lighting and the obstacles. All lengths in the ground frame G (x forward, y left, z up [m]).

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace stereo_ground_dem::sim {

enum class SceneKind { kFlatRoad, kBumpAndCurb, kOffRoad };

/// "flat", "bump", "offroad".
const char* sceneKindName(SceneKind kind);
/// Inverse of sceneKindName(); also accepts "flat_road", "bump_and_curb", "off_road".
bool sceneKindFromName(const std::string& name, SceneKind* kind);

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

  // Road (flat road and bump-and-curb scenes): asphalt, edge lines, dashed centre line.
  double road_center_y_m = 0.0;          ///< road axis [m]
  double road_width_m = 7.5;             ///< asphalt width [m]
  double edge_line_width_m = 0.15;       ///< solid edge lines [m]
  double edge_line_inset_m = 0.20;       ///< from the asphalt edge to the line's outer edge [m]
  double centre_line_width_m = 0.12;     ///< dashed centre line [m]
  double centre_dash_length_m = 3.0;     ///< [m]
  double centre_gap_length_m = 6.0;      ///< [m]
  double centre_dash_phase_m = 1.0;      ///< a dash starts at x = phase + n * (dash + gap) [m]
  double shoulder_width_m = 1.2;         ///< gravel beyond the asphalt, then grass [m]

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

  std::vector<BoxObstacle> boxes;  ///< object ids 1..boxes.size()
  std::vector<PoleObstacle> poles; ///< object ids boxes.size()+1 ..

  /// The three standard scenes (see the package docs); no obstacles.
  static SceneOptions standard(SceneKind kind, uint64_t seed = 1);
  /// Adds a fixed set of obstacles suited to the scene kind: a parked car, a car driving ahead at
  /// 5 m/s, a wall and two poles, all off the driving line near y = 0 except the moving car.
  void addStandardObstacles();

  bool isValid(std::string* why = nullptr) const;
};

}  // namespace stereo_ground_dem::sim
