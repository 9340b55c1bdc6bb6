#pragma once
/// \file StereoRenderer.hpp
/// Renders a SyntheticScene through a rectified stereo rig by per-pixel ray casting, with exact
/// visibility (nearest hit) and exact per-pixel ground truth (inverse depth, object label).
///
/// Conventions: those of StereoRig.hpp. Pixel (u, v) (centres at integers) sees the direction
/// K^{-1} (u, v, 1) of the camera optical frame; `ground_T_camera` maps optical-frame points into
/// the ground frame. With supersampling n, a pixel is the mean of n x n rays at the centres of an
/// n x n grid over the pixel square [u - 1/2, u + 1/2] x [v - 1/2, v + 1/2].
///
/// Image formation: image = round(clamp(gain * albedo + bias_grey + noise, 0, 255)), with albedo the
/// pixel's mean shaded albedo (SyntheticScene::albedo, sky included) and noise i.i.d. Gaussian with
/// standard deviation noise_std_grey, a hash of (RenderOptions::seed, noise_seed, u, v): the same
/// seeds give the same image whatever the number of threads.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/sim/SyntheticScene.hpp"

namespace stereo_ground_dem::sim {

/// Camera response of one image: image = gain * albedo + bias_grey.
struct Photometry {
  double gain = 1.0;
  double bias_grey = 0.0;  ///< [grey]
};

struct RenderOptions {
  int supersampling = 2;         ///< rays per pixel along each axis, 1..8
  double noise_std_grey = 1.0;   ///< sensor noise [grey], >= 0
  uint64_t seed = 0;             ///< mixed into every image's noise seed
  double max_depth_m = 1000.0;   ///< surfaces farther than this (along the optical axis) are sky
  /// Texture band limit (see TextureFilter): octaves fade in between these multiples of the
  /// pixel footprint, which is minor^(1-anisotropy) * major^anisotropy of the footprint ellipse.
  /// Measured on the flat road, 1226 x 370, ground 30-80 m away, mean |albedo(ss 2) - albedo(ss 4)|:
  /// anisotropy 0.5: 2.6 grey, 0.65: 1.0, 0.75: 0.43, 1.0: 0.15; mean horizontal gradient at
  /// 5-8 m: 5.0, 3.9, 3.6, 2.3 grey/px. 0.65 keeps most of the texture without visible aliasing.
  double octave_fade_start = 1.0;
  double octave_fade_end = 2.0;
  double anisotropy = 0.65;

  bool isValid(std::string* why = nullptr) const;
};

struct RenderedImage {
  cv::Mat image;          ///< CV_8U, the camera image
  cv::Mat inverse_depth;  ///< CV_32F, 1 / Z [1/m] of the nearest surface at the pixel centre; 0: sky
  cv::Mat label;          ///< CV_32S, at the pixel centre: 0 terrain, obstacle id > 0, -1 sky
  cv::Mat albedo;         ///< CV_32F, the noise-free pixel mean albedo before gain and bias [grey]
};

struct RenderedPair {
  RenderedImage left;
  RenderedImage right;
};

class StereoRenderer {
 public:
  /// Copies the scene. Throws std::invalid_argument on an invalid rig (or zero image size) or
  /// options.
  StereoRenderer(const SyntheticScene& scene, const StereoRig& rig,
                 const RenderOptions& options = RenderOptions());

  const StereoRig& rig() const { return rig_; }
  const RenderOptions& options() const { return options_; }
  const SyntheticScene& scene() const { return scene_; }

  /// One camera of the rig (the intrinsics and size of `rig`) at `ground_T_camera`.
  RenderedImage render(const Eigen::Isometry3d& ground_T_camera,
                       const Photometry& photometry = Photometry(), double time_s = 0.0,
                       uint64_t noise_seed = 0) const;

  /// Both cameras; the right one is ground_T_left * Translation(baseline_m, 0, 0). Their noise
  /// seeds are derived from `noise_seed` (different for the two images).
  RenderedPair renderPair(const Eigen::Isometry3d& ground_T_left, const Photometry& left,
                          const Photometry& right, double time_s = 0.0,
                          uint64_t noise_seed = 0) const;

  /// ground_T_right for ground_T_left.
  Eigen::Isometry3d rightPose(const Eigen::Isometry3d& ground_T_left) const;

  /// The gray rig of KITTI odometry sequences 04-12 (fx = fy = 707.0912, cx = 601.8873,
  /// cy = 183.1104, baseline 0.5372 m, 1226 x 370), resampled by `scale`: focal lengths times
  /// scale, (c + 1/2) times scale minus 1/2 for the principal point, size rounded.
  static StereoRig kittiLikeRig(double scale = 1.0);

  /// A camera at `position_m` (ground frame) looking horizontally along yaw (0: +x) and then
  /// pitched down by pitch_down_rad (positive looks down), without roll.
  static Eigen::Isometry3d lookingPose(const Eigen::Vector3d& position_m, double yaw_rad = 0.0,
                                       double pitch_down_rad = 0.0);

 private:
  SyntheticScene scene_;
  StereoRig rig_;
  RenderOptions options_;
};

}  // namespace stereo_ground_dem::sim
