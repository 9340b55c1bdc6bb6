#pragma once
/// \file SyntheticScene.hpp
/// An analytic world in the ground frame G (x forward, y left, z up [m]; see GroundGrid.hpp) for
/// exact ground truth: a piecewise-smooth terrain height field, textured materials, and obstacles.
///
/// The facade over three parts, each usable on its own:
///  - TerrainModel: the height field, its axis-parallel feature lines and the slope / curvature
///    bounds between them (what makes exact ray casting possible);
///  - RayCaster: the nearest terrain or obstacle hit along a ray, obstacle footprints;
///  - SurfaceShader: the materials, their band-limited textures and the shading.
/// SceneOptions (SceneOptions.hpp) describes the scene; toYaml / fromYaml store and rebuild it.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <string>

#include "stereo_ground_dem/sim/RayCaster.hpp"
#include "stereo_ground_dem/sim/SceneOptions.hpp"
#include "stereo_ground_dem/sim/SurfaceHit.hpp"
#include "stereo_ground_dem/sim/SurfaceShader.hpp"
#include "stereo_ground_dem/sim/TerrainModel.hpp"
#include "stereo_ground_dem/sim/TextureFilter.hpp"

namespace stereo_ground_dem::sim {

class SyntheticScene {
 public:
  /// Throws std::invalid_argument (with SceneOptions::isValid's reason) on invalid options.
  explicit SyntheticScene(const SceneOptions& options = SceneOptions());

  const SceneOptions& options() const { return options_; }
  const TerrainModel& terrain() const { return *terrain_; }
  const RayCaster& rayCaster() const { return *caster_; }
  const SurfaceShader& shader() const { return *shader_; }

  /// Exact terrain height [m] at (x, y) (obstacles excluded). Region tests are strict: the
  /// sidewalk is y < curb_y_m, the terrace x > terrace_x_min_m && y > terrace_y_min_m.
  double terrainHeight(double x, double y) const { return terrain_->height(x, y); }
  /// Gradient (dz/dx, dz/dy) of the smooth part at (x, y) (the steps have none).
  Eigen::Vector2d terrainGradient(double x, double y) const { return terrain_->gradient(x, y); }
  /// Terrain height, or the top of an obstacle whose footprint contains (x, y) at time_s.
  double surfaceHeight(double x, double y, double time_s = 0.0) const {
    return caster_->surfaceHeight(x, y, time_s);
  }

  /// Lowest and highest terrain height anywhere [m].
  double minTerrainHeight() const { return terrain_->minHeight(); }
  double maxTerrainHeight() const { return terrain_->maxHeight(); }

  int obstacleCount() const { return static_cast<int>(options_.boxes.size() + options_.poles.size()); }
  /// Object id of an obstacle whose footprint contains (x, y) at time_s, 0 if none.
  int obstacleIdAt(double x, double y, double time_s = 0.0) const {
    return caster_->obstacleIdAt(x, y, time_s);
  }
  bool insideObstacleFootprint(double x, double y, double time_s = 0.0) const {
    return obstacleIdAt(x, y, time_s) > 0;
  }

  /// The nearest surface (terrain or obstacle) hit by the ray o + t d, 0 < t <= t_max (d need
  /// not be unit). Exact up to ~1e-6 m along z for the terrain, to rounding for obstacles.
  SurfaceHit intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max,
                       double time_s = 0.0) const {
    return caster_->intersect(o, d, t_max, time_s);
  }

  /// Shaded albedo [grey] at a hit, band-limited for the footprint in `filter`.
  double albedo(const SurfaceHit& hit, const TextureFilter& filter, double time_s = 0.0) const {
    return shader_->albedo(hit, filter, time_s);
  }

  /// Sky brightness [grey] for a ray direction (a smooth gradient, brightest at the horizon).
  static double skyAlbedo(const Eigen::Vector3d& d) { return SurfaceShader::skyAlbedo(d); }

  /// YAML (cv::FileStorage) with every SceneOptions field; fromYaml(toYaml) rebuilds the scene
  /// exactly. Both throw std::runtime_error naming the file on failure.
  void toYaml(const std::string& path) const;
  static SyntheticScene fromYaml(const std::string& path);
  static SceneOptions optionsFromYaml(const std::string& path);

 private:
  SceneOptions options_;
  // Immutable parts, shared between copies of the scene.
  std::shared_ptr<const TerrainModel> terrain_;
  std::shared_ptr<const RayCaster> caster_;
  std::shared_ptr<const SurfaceShader> shader_;
};

}  // namespace stereo_ground_dem::sim
