// dem_node: stereo_ground_dem/DemNodelet as a standalone node (same topics, parameters and
// services; the nodelet runs in this process's own nodelet loader).
//   rosrun stereo_ground_dem dem_node left/image_rect:=... _base_frame:=base_link
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "stereo_ground_dem");
  nodelet::Loader loader(false);  // no manager services: this process hosts one nodelet
  const nodelet::M_string remappings(ros::names::getRemappings());
  const nodelet::V_string args(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "stereo_ground_dem/DemNodelet", remappings, args)) {
    ROS_FATAL("could not start stereo_ground_dem/DemNodelet (the reason is logged above)");
    return 1;
  }
  ros::spin();
  return 0;
}
