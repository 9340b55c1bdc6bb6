#pragma once
/// \file SurfaceShader.hpp
/// The appearance of a SyntheticScene: textured materials (road with lane paint, gravel, grass,
/// dirt track, rock, concrete, obstacle paint) and their Lambertian shading by a fixed sun.
///
/// Albedo: grey levels before camera gain and bias (roughly 40..220), Lambertian-shaded by the
/// sun, so it is the same for every viewpoint. Textures are hash-based gradient noise in octaves
/// from 16 m down to 1.6 cm, band-limited to the footprint of the sample (TextureFilter) so that
/// distant surfaces do not alias.

#include <Eigen/Core>
#include <memory>

#include "stereo_ground_dem/sim/SceneOptions.hpp"
#include "stereo_ground_dem/sim/SurfaceHit.hpp"
#include "stereo_ground_dem/sim/TextureFilter.hpp"
#include "stereo_ground_dem/sim/TextureNoise.hpp"

namespace stereo_ground_dem::sim {

class SurfaceShader {
 public:
  /// `options` must be valid.
  explicit SurfaceShader(const SceneOptions& options);

  /// Shaded albedo [grey] at a hit, band-limited for the footprint in `filter`.
  double albedo(const SurfaceHit& hit, const TextureFilter& filter, double time_s = 0.0) const;

  /// Sky brightness [grey] for a ray direction (a smooth gradient, brightest at the horizon).
  static double skyAlbedo(const Eigen::Vector3d& d);

 private:
  double terrainAlbedo(const SurfaceHit& hit, const TextureFilter& filter) const;
  double obstacleAlbedo(const SurfaceHit& hit, const TextureFilter& filter, double time_s) const;
  double shading(const Eigen::Vector3d& normal) const;

  SceneOptions options_;
  Eigen::Vector3d sun_ = Eigen::Vector3d::UnitZ();
  double flat_shading_ = 1.0;
  TextureNoise ground_noise_;
  TextureNoise detail_noise_;  ///< material borders, wear
};

}  // namespace stereo_ground_dem::sim
