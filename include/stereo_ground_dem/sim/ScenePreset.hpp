#pragma once
/// \file ScenePreset.hpp
/// The scene zoo: for every SceneKind, the scene (SceneOptions) and the drive through it
/// (SequenceOptions: trajectory, speed, attitude), so that `sgd_render --scene NAME --frames N
/// --out DIR` renders the intended sequence with no other flag. docs/zoo.md describes each one:
/// what it tests and the ground truth it carries.
///
/// Common to all: the KITTI-like rig of StereoRenderer::kittiLikeRig, the camera 1.65 m above the
/// ground, 10 frames per second. The zoo's roads are driven in the right-hand lane; the vehicle
/// starts at the origin of G heading along +x (the first three scenes as before).

#include <cstdint>
#include <string>
#include <vector>

#include "stereo_ground_dem/sim/SceneOptions.hpp"
#include "stereo_ground_dem/sim/SequenceGenerator.hpp"

namespace stereo_ground_dem::sim {

struct ScenePreset {
  SceneOptions scene;
  SequenceOptions sequence;  ///< frames left at the default: the caller sets them

  /// The preset of `kind` with texture / terrain seed `seed` (the sequence's noise seed too).
  static ScenePreset forKind(SceneKind kind, uint64_t seed = 1);
};

}  // namespace stereo_ground_dem::sim
