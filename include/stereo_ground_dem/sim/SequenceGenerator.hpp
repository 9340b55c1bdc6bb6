#pragma once
/// \file SequenceGenerator.hpp
/// A vehicle driving through a SyntheticScene: the left camera's trajectory and photometry per frame,
/// rendering, and export as a KITTI-odometry-style folder with exact ground truth.
///
/// Vehicle model: the vehicle's reference point moves in the x-y plane, either freely (from
/// start_xy_m, heading start_yaw_rad, speed_m_per_frame along the heading, yaw changing by
/// yaw_rate_rad_per_frame) or along the scene's road path (follow_road_path: position and heading
/// from the path at a constant offset, speed_m_per_frame along the vehicle's own parallel of it).
/// Its body rests on the terrain: the plane through the heights under the four corners of a
/// vehicle_length_m x vehicle_width_m footprint centred on the reference point (least squares)
/// gives its pitch and roll and the ground point under it. An optional attitude perturbation then
/// pitches and rolls the body about that ground point (a body moving on its suspension). The left
/// camera sits camera_height_m above the ground point along the body's up axis, looks along the
/// body's forward axis, pitched down by camera_pitch_down_rad. Obstacles are ignored by the vehicle
/// model. Every pose is computed in closed form: exact ground truth.
///
/// Folder layout written by writeKitti(dir):
///   calib.txt              P0:/P1: rectified 3x4 projections (P1(0,3) = -fx * baseline)
///   image_0/%06d.png       left images (CV_8U)       image_1/%06d.png  right images
///   times.txt              one time [s] per line
///   poses.txt              per frame, 12 numbers: the 3x4 row-major [R|t] of camera0_T_cameraK
///   ground_T_camera0.txt   16 numbers, row-major: the pose of the first left camera in the scene
///   photometry.txt         per frame: gain_left bias_left gain_right bias_right
///   scene.yaml             SyntheticScene::toYaml (rebuild with SyntheticScene::fromYaml)
///   disp_0/%06d.png        (write_truth_maps) left disparity at pixel centres, KITTI format:
///                          uint16 = round(256 * disparity [px]), 0 where nothing is hit (sky)
///   label_0/%06d.png       (write_truth_maps) uint16 label + 1: 0 sky, 1 terrain, 1 + obstacle id

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/sim/StereoRenderer.hpp"
#include "stereo_ground_dem/sim/SyntheticScene.hpp"

namespace stereo_ground_dem::sim {

struct SequenceOptions {
  int frames = 10;                       ///< number of stereo pairs, >= 1
  double speed_m_per_frame = 1.0;        ///< [m/frame], >= 0
  double frame_period_s = 0.1;           ///< [s], > 0
  Eigen::Vector2d start_xy_m = Eigen::Vector2d::Zero();  ///< vehicle reference point at frame 0
  double start_yaw_rad = 0.0;            ///< heading at frame 0 (0: +x)
  double yaw_rate_rad_per_frame = 0.0;   ///< [rad/frame]
  double camera_height_m = 1.65;         ///< above the ground point under the vehicle [m]
  double camera_pitch_down_rad = 0.0;    ///< positive: looking down [rad]
  double vehicle_length_m = 2.7;         ///< wheel footprint [m]
  double vehicle_width_m = 1.6;          ///< [m]
  double gain_start = 1.0;               ///< left gain at frame 0; linear drift to gain_end
  double gain_end = 1.0;                 ///< left gain at the last frame
  double right_gain_ratio = 1.0;         ///< right gain = left gain * ratio
  double left_bias_grey = 0.0;           ///< [grey]
  double right_bias_grey = 0.0;          ///< [grey]
  uint64_t noise_seed = 1;               ///< image noise seed of the sequence (and attitude jitter)
  bool write_truth_maps = true;          ///< writeKitti also writes disp_0/ and label_0/

  /// Follow the scene's road path (which must have one) instead of start pose and yaw rate: the
  /// reference point keeps the offset path_offset_m (positive left) from the path, frame k is
  /// path_start_m + k * speed_m_per_frame along that parallel from the path's anchor (s = 0), and
  /// the heading is the path's.
  bool follow_road_path = false;
  double path_offset_m = 0.0;            ///< [m]
  double path_start_m = 0.0;             ///< [m]

  /// Attitude perturbation: frame k pitches the body (nose down positive) by (-1)^k (pitch
  /// amplitude + j) and rolls it (left side up positive) by -(-1)^k (roll amplitude + j'), with
  /// j, j' uniform in [-attitude_jitter_rad, attitude_jitter_rad] from noise_seed, so consecutive
  /// frames differ by about twice the amplitudes. Zero: the body follows the terrain only.
  double attitude_pitch_rad = 0.0;       ///< [rad], |.| < 0.3
  double attitude_roll_rad = 0.0;        ///< [rad], |.| < 0.3
  double attitude_jitter_rad = 0.0;      ///< [rad], >= 0, < 0.1

  bool isValid(std::string* why = nullptr) const;
};

struct SequenceFrame {
  int index = 0;
  double time_s = 0.0;
  Eigen::Isometry3d ground_T_left = Eigen::Isometry3d::Identity();
  Photometry left;
  Photometry right;
};

class SequenceGenerator {
 public:
  /// Computes the trajectory. Throws std::invalid_argument on invalid options or rig.
  SequenceGenerator(const SyntheticScene& scene, const StereoRig& rig,
                    const SequenceOptions& options = SequenceOptions(),
                    const RenderOptions& render_options = RenderOptions());

  const std::vector<SequenceFrame>& frames() const { return frames_; }
  const SequenceOptions& options() const { return options_; }
  const StereoRenderer& renderer() const { return renderer_; }

  /// The left camera pose for a vehicle reference point (x, y) and heading `yaw_rad` on `scene`,
  /// with the body additionally pitched (nose down positive) and rolled (left side up positive)
  /// about the ground point under it.
  static Eigen::Isometry3d cameraPose(const SyntheticScene& scene, const SequenceOptions& options,
                                      double x, double y, double yaw_rad,
                                      double extra_pitch_rad = 0.0, double extra_roll_rad = 0.0);
  /// The vehicle reference point (x, y) and heading of frame k (before the body is put on the
  /// terrain) and the attitude perturbation of frame k.
  Eigen::Vector3d vehicleXyYaw(int k) const { return xy_yaw_.at(static_cast<size_t>(k)); }
  Eigen::Vector2d attitudePerturbation(int k) const {
    return perturbation_.at(static_cast<size_t>(k));
  }

  /// Renders frame k (0 <= k < frames().size()).
  RenderedPair render(int k) const;

  /// Writes the whole sequence (see the file comment). Creates `dir` if needed; throws
  /// std::runtime_error naming the file that could not be written.
  void writeKitti(const std::string& dir) const;

 private:
  StereoRenderer renderer_;
  SequenceOptions options_;
  std::vector<SequenceFrame> frames_;
  std::vector<Eigen::Vector3d> xy_yaw_;        ///< per frame: x, y [m], heading [rad]
  std::vector<Eigen::Vector2d> perturbation_;  ///< per frame: pitch, roll [rad]
};

}  // namespace stereo_ground_dem::sim
