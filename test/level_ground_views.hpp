#pragma once
// Shared by the ortho-texture, photometric-residual and map-window tests: a KITTI-like rig over a
// level, smoothly textured ground, its exact images and a level map.
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {
namespace test {

inline StereoRig levelGroundRig() {
  StereoRig r;
  r.fx = r.fy = 700.0;
  r.cx = 600.0;
  r.cy = 180.0;
  r.baseline_m = 0.54;
  r.width = 1200;
  r.height = 370;
  return r;
}

/// A camera 1.65 m above the ground at (x, 0), looking along +x (camera x = -y, y = -z, z = +x).
inline Eigen::Isometry3d levelGroundCamera(double x) {
  Eigen::Isometry3d g = Eigen::Isometry3d::Identity();
  g.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  g.translation() = Eigen::Vector3d(x, 0.0, 1.65);
  return g;
}

/// The ground's grey level at (x, y): smooth, so that a bilinear image sample is exact to ~0.1 grey.
/// Along x the wave is long: 30 m ahead a pixel spans 0.7 m of ground along the view.
inline double levelGroundAlbedo(double x, double y) {
  return 120.0 + 40.0 * std::sin(2.0 * M_PI * x / 8.0) + 30.0 * std::cos(2.0 * M_PI * y / 1.5);
}

/// The image of the level ground z = 0 (albedo * gain + bias) seen from `g_t_c`; the sky is 250.
inline cv::Mat levelGroundImage(const Eigen::Isometry3d& g_t_c, double gain = 1.0, double bias = 0.0,
                                double offset = 0.0) {
  const StereoRig k = levelGroundRig();
  cv::Mat im(k.height, k.width, CV_32F);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Eigen::Vector3d d = g_t_c.linear() * Eigen::Vector3d((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      if (d.z() >= -1e-6) {
        im.at<float>(v, u) = 250.0f;
        continue;
      }
      const double t = -g_t_c.translation().z() / d.z();
      const Eigen::Vector3d p = g_t_c.translation() + t * d;
      im.at<float>(v, u) = static_cast<float>(gain * (levelGroundAlbedo(p.x(), p.y()) + offset) + bias);
    }
  }
  return im;
}

/// A level map (heights 0) over x 0..60 m, y -20..20 m.
inline ElevationMap levelGroundMap(GroundGrid* window) {
  *window = GroundGrid::covering(0.0, 60.0, -20.0, 20.0, 0.5);
  ElevationMap map;
  const int n = window->vertexCount();
  map.fuse(*window, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Constant(n, 1e4),
           std::vector<uint8_t>(static_cast<size_t>(n), 1), 0);
  return map;
}

}  // namespace test
}  // namespace stereo_ground_dem
