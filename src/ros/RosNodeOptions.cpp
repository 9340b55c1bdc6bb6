#include "stereo_ground_dem/ros/RosNodeOptions.hpp"

#include <cmath>
#include <stdexcept>

namespace stereo_ground_dem {

const std::vector<std::string>& RosNodeOptions::names() {
  static const std::vector<std::string> kNames = {
      "queue_size", "approximate_sync", "slop_s", "lazy", "tune_allocator", "release_memory_every_frames", "start_hold_frames", "odom_frame", "base_frame", "camera_frame",
      "publish_tf", "tf_wait_s", "mount_from_tf", "footprint_frame", "local_map_size_m", "local_map_forward_m", "global_map_rate_hz",
      "global_map_max_cells", "mesh_max_triangles", "mesh_colors", "occupancy_unknown_below", "occupancy_min_certainty", "path_max_poses",
      "save_directory", "diagnostic_period_s", "input_check_period_s", "unobserved_std_m", "unobserved_std_rad",
      "motion_covariance_scale",
      "restart_back_s", "max_stamp_gap_s", "image_transport"};
  return kNames;
}

RosNodeOptions RosNodeOptions::load(const ros::NodeHandle& pnh) {
  RosNodeOptions o;
  pnh.param("queue_size", o.queue_size, o.queue_size);
  pnh.param("approximate_sync", o.approximate_sync, o.approximate_sync);
  pnh.param("slop_s", o.slop_s, o.slop_s);
  pnh.param("lazy", o.lazy, o.lazy);
  pnh.param("tune_allocator", o.tune_allocator, o.tune_allocator);
  pnh.param("release_memory_every_frames", o.release_memory_every_frames, o.release_memory_every_frames);
  pnh.param("start_hold_frames", o.start_hold_frames, o.start_hold_frames);
  pnh.param("odom_frame", o.odom_frame, o.odom_frame);
  pnh.param("base_frame", o.base_frame, o.base_frame);
  pnh.param("camera_frame", o.camera_frame, o.camera_frame);
  pnh.param("publish_tf", o.publish_tf, o.publish_tf);
  pnh.param("tf_wait_s", o.tf_wait_s, o.tf_wait_s);
  pnh.param("mount_from_tf", o.mount_from_tf, o.mount_from_tf);
  pnh.param("footprint_frame", o.footprint_frame, o.footprint_frame);
  pnh.param("local_map_size_m", o.local_map_size_m, o.local_map_size_m);
  pnh.param("local_map_forward_m", o.local_map_forward_m, o.local_map_forward_m);
  pnh.param("global_map_rate_hz", o.global_map_rate_hz, o.global_map_rate_hz);
  pnh.param("global_map_max_cells", o.global_map_max_cells, o.global_map_max_cells);
  pnh.param("mesh_max_triangles", o.mesh.max_triangles, o.mesh.max_triangles);
  std::string mesh_colors = "height";
  pnh.param("mesh_colors", mesh_colors, mesh_colors);
  if (mesh_colors == "intensity") o.mesh.colors = MeshColors::kIntensity;
  if (mesh_colors == "residual") o.mesh.colors = MeshColors::kResidual;
  pnh.param("occupancy_unknown_below", o.occupancy_unknown_below, o.occupancy_unknown_below);
  pnh.param("occupancy_min_certainty", o.occupancy_min_certainty, o.occupancy_min_certainty);
  pnh.param("path_max_poses", o.path_max_poses, o.path_max_poses);
  pnh.param("save_directory", o.save_directory, o.save_directory);
  pnh.param("diagnostic_period_s", o.diagnostic_period_s, o.diagnostic_period_s);
  pnh.param("input_check_period_s", o.input_check_period_s, o.input_check_period_s);
  pnh.param("unobserved_std_m", o.unobserved_std_m, o.unobserved_std_m);
  pnh.param("unobserved_std_rad", o.unobserved_std_rad, o.unobserved_std_rad);
  pnh.param("motion_covariance_scale", o.motion_covariance_scale, o.motion_covariance_scale);
  pnh.param("restart_back_s", o.restart_back_s, o.restart_back_s);
  pnh.param("max_stamp_gap_s", o.max_stamp_gap_s, o.max_stamp_gap_s);
  pnh.param("image_transport", o.image_transport, o.image_transport);
  std::vector<std::string> bad;
  if (o.queue_size < 1) bad.push_back("~queue_size must be >= 1");
  if (o.release_memory_every_frames < 0) bad.push_back("~release_memory_every_frames must be >= 0");
  if (o.start_hold_frames < 0) bad.push_back("~start_hold_frames must be >= 0");
  if (!(o.slop_s > 0.0)) bad.push_back("~slop_s must be > 0");
  if (o.odom_frame.empty()) bad.push_back("~odom_frame must not be empty");
  if (!(o.local_map_size_m > 0.0)) bad.push_back("~local_map_size_m must be > 0");
  if (!(o.global_map_rate_hz >= 0.0)) bad.push_back("~global_map_rate_hz must be >= 0");
  if (o.global_map_max_cells < 4) bad.push_back("~global_map_max_cells must be >= 4");
  if (o.mesh.max_triangles < 2) bad.push_back("~mesh_max_triangles must be >= 2");
  if (mesh_colors != "height" && mesh_colors != "intensity" && mesh_colors != "residual") {
    bad.push_back("~mesh_colors must be 'height', 'intensity' or 'residual', got '" + mesh_colors + "'");
  }
  if (o.path_max_poses < 1) bad.push_back("~path_max_poses must be >= 1");
  if (!(o.occupancy_min_certainty >= 0.0 && o.occupancy_min_certainty <= 1.0)) {
    bad.push_back("~occupancy_min_certainty must be in 0..1");
  }
  if (!(o.unobserved_std_m > 0.0) || !(o.unobserved_std_rad > 0.0)) bad.push_back("~unobserved_std_* must be > 0");
  if (!(o.motion_covariance_scale > 0.0) || !std::isfinite(o.motion_covariance_scale)) {
    bad.push_back("~motion_covariance_scale must be > 0");
  }
  if (!(o.diagnostic_period_s > 0.0) || !(o.input_check_period_s > 0.0)) bad.push_back("~*_period_s must be > 0");
  if (!(o.restart_back_s >= 0.0)) bad.push_back("~restart_back_s must be >= 0");
  if (!(o.max_stamp_gap_s > 0.0)) bad.push_back("~max_stamp_gap_s must be > 0");
  if (!bad.empty()) {
    std::string s;
    for (size_t i = 0; i < bad.size(); ++i) s += (i ? ", " : "") + bad[i];
    throw std::invalid_argument(s);
  }
  return o;
}

}  // namespace stereo_ground_dem
