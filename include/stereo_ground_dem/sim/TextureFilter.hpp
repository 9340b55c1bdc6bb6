#pragma once
/// \file TextureFilter.hpp
/// The band limit of one texture sample (filled by the renderer, used by SurfaceShader).

#include <Eigen/Core>

namespace stereo_ground_dem::sim {

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

}  // namespace stereo_ground_dem::sim
