#pragma once
/// \file SyntheticScene.hpp
/// An analytic world in the ground frame G (x forward, y left, z up [m]; see GroundGrid.hpp) for
/// exact ground truth: a piecewise-smooth terrain height field, textured materials, and obstacles.
///
/// Terrain model (what makes exact ray casting possible):
///  - terrainHeight(x, y) = smooth part + piecewise-constant steps;
///  - every step (curb, terrace) and every edge of a feature's support (bump, ruts, embankment
///    kinks) lies on an axis-parallel line x = const or y = const ("feature lines");
///  - between feature lines, the smooth part is C1 with known bounds on its slope and curvature, so
///    a ray can be marched with provably safe steps; at a feature line, a ray below the terrain on
///    the far side hits a vertical face exactly on that line.
///
/// Albedo: grey levels before camera gain and bias (roughly 40..220), Lambertian-shaded by a fixed
/// sun (no cast shadows), so it is the same for every viewpoint. Textures are hash-based gradient
/// noise in octaves from 16 m down to 1.6 cm, band-limited to the footprint of the sample
/// (TextureFilter) so that distant surfaces do not alias.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "stereo_ground_dem/sim/TextureNoise.hpp"

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

/// Everything the texturing of one sample needs beyond the hit point (filled by the renderer).
struct TextureFilter {
  Eigen::Vector3d dp_du = Eigen::Vector3d::Zero();  ///< surface point change per pixel along u [m/px]
  Eigen::Vector3d dp_dv = Eigen::Vector3d::Zero();  ///< ... along v [m/px]
  /// Noise octaves fade in between these multiples of the footprint (wavelength / footprint).
  double octave_fade_start = 1.0;
  double octave_fade_end = 2.0;
  /// Footprint used for the octave cut: minor^(1-a) * major^a of the pixel's footprint ellipse
  /// (0: the minor axis, sharp but aliasing along the major one; 1: the major axis, blurred).
  double anisotropy = 0.65;
  /// Width of the box filter applied to hard material edges (lane markings, borders) [px]; the
  /// sub-sample size (1 / supersampling) makes supersampled edges an exact area average.
  double edge_box_px = 0.5;
};

/// The nearest surface along a ray.
struct SurfaceHit {
  // Values of `surface`.
  static constexpr int kTerrainTop = 0;
  static constexpr int kTerrainFaceX = 1;  ///< vertical terrain face on a line x = const
  static constexpr int kTerrainFaceY = 2;  ///< vertical terrain face on a line y = const
  /// Box faces: kBoxFaceBase + 2 * axis + (positive side ? 1 : 0); axis 0 length, 1 width, 2 up.
  static constexpr int kBoxFaceBase = 10;
  static constexpr int kPoleSide = 20;
  static constexpr int kPoleTop = 21;

  double t = std::numeric_limits<double>::infinity();  ///< ray parameter (point = o + t d)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    ///< [m], ground frame
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit, facing the ray origin
  int object_id = -1;  ///< 0 terrain, > 0 obstacle, -1 nothing hit
  int surface = kTerrainTop;  ///< which part of the object (see the constants above)
  bool hit() const { return object_id >= 0; }
};

class SyntheticScene {
 public:
  /// Throws std::invalid_argument (with SceneOptions::isValid's reason) on invalid options.
  explicit SyntheticScene(const SceneOptions& options = SceneOptions());

  const SceneOptions& options() const { return options_; }

  /// Exact terrain height [m] at (x, y) (obstacles excluded). Region tests are strict: the
  /// sidewalk is y < curb_y_m, the terrace x > terrace_x_min_m && y > terrace_y_min_m.
  double terrainHeight(double x, double y) const;
  /// Gradient (dz/dx, dz/dy) of the smooth part at (x, y) (the steps have none).
  Eigen::Vector2d terrainGradient(double x, double y) const;
  /// Terrain height, or the top of an obstacle whose footprint contains (x, y) at time_s.
  double surfaceHeight(double x, double y, double time_s = 0.0) const;

  /// Lowest and highest terrain height anywhere [m].
  double minTerrainHeight() const { return z_min_; }
  double maxTerrainHeight() const { return z_max_; }

  int obstacleCount() const { return static_cast<int>(options_.boxes.size() + options_.poles.size()); }
  /// Object id of an obstacle whose footprint contains (x, y) at time_s, 0 if none.
  int obstacleIdAt(double x, double y, double time_s = 0.0) const;
  bool insideObstacleFootprint(double x, double y, double time_s = 0.0) const {
    return obstacleIdAt(x, y, time_s) > 0;
  }

  /// The nearest surface (terrain or obstacle) hit by the ray o + t d, 0 < t <= t_max (d need
  /// not be unit). Exact up to ~1e-6 m along z for the terrain, to rounding for obstacles.
  SurfaceHit intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max,
                       double time_s = 0.0) const;

  /// Shaded albedo [grey] at a hit, band-limited for the footprint in `filter`.
  double albedo(const SurfaceHit& hit, const TextureFilter& filter, double time_s = 0.0) const;

  /// Sky brightness [grey] for a ray direction (a smooth gradient, brightest at the horizon).
  static double skyAlbedo(const Eigen::Vector3d& d);

  /// YAML (cv::FileStorage) with every SceneOptions field; fromYaml(toYaml) rebuilds the scene
  /// exactly. Both throw std::runtime_error naming the file on failure.
  void toYaml(const std::string& path) const;
  static SyntheticScene fromYaml(const std::string& path);
  static SceneOptions optionsFromYaml(const std::string& path);

 private:
  struct RollingWave {
    double kx, ky;  ///< wave vector [rad/m]
    double amp;     ///< [m]
    double phase;   ///< [rad]
  };
  struct Cell;       // which features are active between two feature lines
  struct RayBounds;  // per-ray directional slope / curvature bounds of each feature

  Cell cellAt(double x, double y) const;
  /// Height and gradient at (x, y) with the features of `cell` (one-sided values on lines).
  double heightInCell(double x, double y, const Cell& cell, double* gx, double* gy) const;
  SurfaceHit intersectTerrain(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                              double t_max) const;
  SurfaceHit intersectObstacles(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max,
                                double time_s) const;
  double terrainAlbedo(const SurfaceHit& hit, const TextureFilter& filter) const;
  double obstacleAlbedo(const SurfaceHit& hit, const TextureFilter& filter, double time_s) const;
  double shading(const Eigen::Vector3d& normal) const;

  SceneOptions options_;
  std::vector<RollingWave> waves_;
  double rolling_offset_m_ = 0.0;
  double rolling_amp_sum_m_ = 0.0;
  double embankment_tan_ = 0.0;       ///< tan(embankment_slope_rad)
  double embankment_top_y_m_ = 0.0;   ///< where the embankment slope ends
  std::vector<double> x_lines_;  ///< feature lines x = const
  std::vector<double> y_lines_;  ///< feature lines y = const
  double z_min_ = 0.0;
  double z_max_ = 0.0;
  Eigen::Vector3d sun_ = Eigen::Vector3d::UnitZ();
  double flat_shading_ = 1.0;
  TextureNoise ground_noise_;
  TextureNoise detail_noise_;  ///< material borders, wear
};

}  // namespace stereo_ground_dem::sim
