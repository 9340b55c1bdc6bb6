#pragma once
/// \file StereoFrame.hpp
/// One validated synchronized stereo frame on its way from the image callback to the processing
/// thread (DemWorker): the images as cv::Mat (sharing the messages' buffers when no conversion was
/// needed; the message pointers keep them alive), the rig from camera_info and the stamp.

#include <ros/time.h>
#include <sensor_msgs/Image.h>

#include <opencv2/core.hpp>
#include <string>

#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

struct StereoFrame {
  sensor_msgs::ImageConstPtr left_msg, right_msg;  ///< owners of the buffers `left`/`right` may share
  cv::Mat left, right;                             ///< what the core gets (any type ImagePyramid accepts)
  ImagePyramid::ColorOrder order = ImagePyramid::ColorOrder::kBgr;
  StereoRig rig;                                   ///< from the camera_info pair
  ros::Time stamp;                                 ///< the left image's header stamp (capture time)
  std::string camera_frame;                        ///< optical frame of the left camera
  ros::WallTime received;                          ///< when the synchronized callback got it
};

}  // namespace stereo_ground_dem
