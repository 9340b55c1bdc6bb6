#include "stereo_ground_dem/sim/StereoRenderer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stereo_ground_dem::sim {

namespace {

// Standard normal value from a 64-bit key (Box-Muller on two hashed uniforms).
double gaussianFromKey(uint64_t key) {
  const uint64_t h = TextureNoise::mix64(key);
  const double u1 = (static_cast<double>(h >> 32) + 0.5) / 4294967296.0;
  const double u2 = static_cast<double>(h & 0xFFFFFFFFULL) / 4294967296.0;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace

bool RenderOptions::isValid(std::string* why) const {
  auto bad = [why](const char* msg) {
    if (why) *why = msg;
    return false;
  };
  if (supersampling < 1 || supersampling > 8) return bad("supersampling must be 1..8");
  if (!(noise_std_grey >= 0.0) || !std::isfinite(noise_std_grey)) {
    return bad("noise_std_grey must be finite and >= 0");
  }
  if (!(max_depth_m > 0.0)) return bad("max_depth_m must be positive");
  if (!(octave_fade_start >= 0.0) || !(octave_fade_end > octave_fade_start)) {
    return bad("need 0 <= octave_fade_start < octave_fade_end");
  }
  if (!(anisotropy >= 0.0 && anisotropy <= 1.0)) return bad("anisotropy must be in [0, 1]");
  return true;
}

StereoRenderer::StereoRenderer(const SyntheticScene& scene, const StereoRig& rig,
                               const RenderOptions& options)
    : scene_(scene), rig_(rig), options_(options) {
  std::string why;
  if (!rig_.isValid(&why)) throw std::invalid_argument("StereoRenderer: rig: " + why);
  if (rig_.width <= 0 || rig_.height <= 0) {
    throw std::invalid_argument("StereoRenderer: the rig needs an image size");
  }
  if (!options_.isValid(&why)) throw std::invalid_argument("RenderOptions: " + why);
}

StereoRig StereoRenderer::kittiLikeRig(double scale) {
  StereoRig rig;
  rig.fx = 707.0912 * scale;
  rig.fy = 707.0912 * scale;
  // Scaling about the image corner (pixel centres at integers: u' + 1/2 = s (u + 1/2)).
  rig.cx = (601.8873 + 0.5) * scale - 0.5;
  rig.cy = (183.1104 + 0.5) * scale - 0.5;
  rig.baseline_m = 379.8145 / 707.0912;
  rig.width = static_cast<int>(std::lround(1226 * scale));
  rig.height = static_cast<int>(std::lround(370 * scale));
  return rig;
}

Eigen::Isometry3d StereoRenderer::lookingPose(const Eigen::Vector3d& position_m, double yaw_rad,
                                              double pitch_down_rad) {
  // Optical axes in a level vehicle frame (x forward, y left, z up): x_c = -y, y_c = -z, z_c = x.
  Eigen::Matrix3d vehicle_R_camera;
  vehicle_R_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Matrix3d pitch =
      Eigen::AngleAxisd(-pitch_down_rad, Eigen::Vector3d::UnitX()).toRotationMatrix();
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
               vehicle_R_camera * pitch;
  t.translation() = position_m;
  return t;
}

Eigen::Isometry3d StereoRenderer::rightPose(const Eigen::Isometry3d& ground_T_left) const {
  return ground_T_left * Eigen::Translation3d(rig_.baseline_m, 0.0, 0.0);
}

RenderedImage StereoRenderer::render(const Eigen::Isometry3d& ground_T_camera,
                                     const Photometry& photometry, double time_s,
                                     uint64_t noise_seed) const {
  const int w = rig_.width, h = rig_.height;
  RenderedImage out;
  out.image.create(h, w, CV_8U);
  out.inverse_depth.create(h, w, CV_32F);
  out.label.create(h, w, CV_32S);
  out.albedo.create(h, w, CV_32F);

  const Eigen::Matrix3d r = ground_T_camera.linear();
  const Eigen::Vector3d o = ground_T_camera.translation();
  const double fx = rig_.fx, fy = rig_.fy, cx = rig_.cx, cy = rig_.cy;
  // d(u, v) = R K^{-1} (u, v, 1) is affine in (u, v).
  const Eigen::Vector3d d_du = r.col(0) / fx;
  const Eigen::Vector3d d_dv = r.col(1) / fy;
  const Eigen::Vector3d d_00 = r.col(2) - cx * d_du - cy * d_dv;
  const int n = options_.supersampling;
  const double inv_n2 = 1.0 / (n * n);
  const bool centre_is_sample = (n % 2) == 1;
  const double t_max = options_.max_depth_m;  // t is the depth Z: the optical-frame z of d is 1
  TextureFilter filter_proto;
  filter_proto.octave_fade_start = options_.octave_fade_start;
  filter_proto.octave_fade_end = options_.octave_fade_end;
  filter_proto.anisotropy = options_.anisotropy;
  filter_proto.edge_box_px = 1.0 / n;
  const uint64_t image_key = TextureNoise::mix64(options_.seed ^ TextureNoise::mix64(noise_seed));
  const double noise_std = options_.noise_std_grey;

  auto shade = [&](const Eigen::Vector3d& d, const SurfaceHit& hit) {
    if (!hit.hit()) return SyntheticScene::skyAlbedo(d);
    TextureFilter f = filter_proto;
    // Change of the hit point per pixel step (the ray/plane intersection differentiated).
    const double nd = hit.normal.dot(d);
    const double nd_safe = std::abs(nd) > 1e-12 ? nd : (nd < 0.0 ? -1e-12 : 1e-12);
    f.dp_du = hit.t * (d_du - d * (hit.normal.dot(d_du) / nd_safe));
    f.dp_dv = hit.t * (d_dv - d * (hit.normal.dot(d_dv) / nd_safe));
    return scene_.albedo(hit, f, time_s);
  };

  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v) {
      auto* img = out.image.ptr<uint8_t>(v);
      auto* inv = out.inverse_depth.ptr<float>(v);
      auto* lab = out.label.ptr<int32_t>(v);
      auto* alb = out.albedo.ptr<float>(v);
      for (int u = 0; u < w; ++u) {
        const Eigen::Vector3d dc = d_00 + u * d_du + v * d_dv;
        const SurfaceHit centre = scene_.intersect(o, dc, t_max, time_s);
        inv[u] = centre.hit() ? static_cast<float>(1.0 / centre.t) : 0.0f;
        lab[u] = centre.hit() ? centre.object_id : -1;
        double sum = 0.0;
        for (int j = 0; j < n; ++j) {
          const double vs = v + (j + 0.5) / n - 0.5;
          for (int i = 0; i < n; ++i) {
            const double us = u + (i + 0.5) / n - 0.5;
            if (centre_is_sample && 2 * i + 1 == n && 2 * j + 1 == n) {
              sum += shade(dc, centre);
              continue;
            }
            const Eigen::Vector3d d = d_00 + us * d_du + vs * d_dv;
            sum += shade(d, scene_.intersect(o, d, t_max, time_s));
          }
        }
        const double a = sum * inv_n2;
        alb[u] = static_cast<float>(a);
        double value = photometry.gain * a + photometry.bias_grey;
        if (noise_std > 0.0) {
          const uint64_t key =
              image_key ^ (static_cast<uint64_t>(v) << 32 | static_cast<uint64_t>(u));
          value += noise_std * gaussianFromKey(key);
        }
        img[u] = static_cast<uint8_t>(std::clamp(std::lround(value), 0L, 255L));
      }
    }
  }, h);
  return out;
}

RenderedPair StereoRenderer::renderPair(const Eigen::Isometry3d& ground_T_left,
                                        const Photometry& left, const Photometry& right,
                                        double time_s, uint64_t noise_seed) const {
  RenderedPair pair;
  pair.left = render(ground_T_left, left, time_s, TextureNoise::mix64(noise_seed * 2 + 0));
  pair.right = render(rightPose(ground_T_left), right, time_s,
                      TextureNoise::mix64(noise_seed * 2 + 1));
  return pair;
}

}  // namespace stereo_ground_dem::sim
