#pragma once
/// \file SurfaceShader.hpp
/// The appearance of a SyntheticScene: textured materials (road with lane paint, gravel, grass,
/// dirt track, rock, concrete, obstacle paint) and their Lambertian shading by a fixed sun, with
/// the obstacles' cast shadows on the terrain when SceneOptions::cast_shadows is set.
///
/// Road layout: without a road path the road runs along x; with one, the markings are laid out in
/// the path's coordinates (arc length, offset), the gore hatching included.
///
/// Albedo: grey levels before camera gain and bias (roughly 40..220), Lambertian-shaded by the
/// sun, so it is the same for every viewpoint. Textures are hash-based gradient noise in octaves
/// from 16 m down to 1.6 cm, band-limited to the footprint of the sample (TextureFilter) so that
/// distant surfaces do not alias.

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "stereo_ground_dem/sim/RayCaster.hpp"
#include "stereo_ground_dem/sim/RoadPath.hpp"
#include "stereo_ground_dem/sim/SceneOptions.hpp"
#include "stereo_ground_dem/sim/SurfaceHit.hpp"
#include "stereo_ground_dem/sim/TextureFilter.hpp"
#include "stereo_ground_dem/sim/TextureNoise.hpp"

namespace stereo_ground_dem::sim {

class SurfaceShader {
 public:
  /// `options` must be valid; `caster` (of the same scene) casts the shadow rays.
  SurfaceShader(const SceneOptions& options, std::shared_ptr<const RayCaster> caster);

  /// Shaded albedo [grey] at a hit, band-limited for the footprint in `filter`.
  double albedo(const SurfaceHit& hit, const TextureFilter& filter, double time_s = 0.0) const;

  /// Sky brightness [grey] for a ray direction (a smooth gradient, brightest at the horizon).
  static double skyAlbedo(const Eigen::Vector3d& d);

 private:
  double terrainAlbedo(const SurfaceHit& hit, const TextureFilter& filter) const;
  double obstacleAlbedo(const SurfaceHit& hit, const TextureFilter& filter, double time_s) const;
  double shading(const Eigen::Vector3d& normal) const;
  /// Whether the ray from `p` towards the sun hits an obstacle at time_s.
  bool inShadow(const Eigen::Vector3d& p, double time_s) const;
  /// The octave amplitudes of a material (scaled by the texture contrast).
  const double* amp(int material) const;

  SceneOptions options_;
  RoadPath path_;
  std::shared_ptr<const RayCaster> caster_;
  std::vector<double> material_amp_;  ///< [material][octave]
  Eigen::Vector3d sun_ = Eigen::Vector3d::UnitZ();  ///< unit, towards the sun
  double flat_shading_ = 1.0;
  double shadow_shading_ = 1.0;  ///< ambient share / flat_shading_
  TextureNoise ground_noise_;
  TextureNoise detail_noise_;  ///< material borders, wear
};

}  // namespace stereo_ground_dem::sim
