#pragma once
/// \file DemServices.hpp
/// The services of stereo_ground_dem/DemNodelet (docs/ros.md, "Services"): ~reset, ~save_map,
/// ~load_map and ~get_submap. They read the worker's MapSnapshot (a copy of the map made after the
/// last frame), never the estimator, so they answer while a frame is processed (~load_map hands
/// the directory to the worker, which loads it between frames); advertise them on the
/// multi-threaded node handle.

#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include <mutex>
#include <string>

#include "stereo_ground_dem/GetSubmap.h"
#include "stereo_ground_dem/LoadMap.h"
#include "stereo_ground_dem/SaveMap.h"
#include "stereo_ground_dem/TraversabilityFilter.hpp"
#include "stereo_ground_dem/ros/DemWorker.hpp"
#include "stereo_ground_dem/ros/RosNodeOptions.hpp"

namespace stereo_ground_dem {

class DemServices {
 public:
  /// `node_name` goes into dem.yaml ("mode: ROS node NAME").
  DemServices(DemWorker& worker, const RosNodeOptions& options, const TraversabilityOptions& traversability,
              const std::string& node_name);

  void advertise(ros::NodeHandle& mt_pnh);
  void shutdown();
  void setTraversability(const TraversabilityOptions& options);

  bool reset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool saveMap(SaveMap::Request& req, SaveMap::Response& res);
  bool loadMap(LoadMap::Request& req, LoadMap::Response& res);
  bool getSubmap(GetSubmap::Request& req, GetSubmap::Response& res);

 private:
  TraversabilityOptions traversability() const;

  DemWorker& worker_;
  const RosNodeOptions options_;
  const std::string node_name_;
  mutable std::mutex mutex_;
  TraversabilityOptions traversability_;
  ros::ServiceServer srv_reset_, srv_save_, srv_submap_, srv_load_;
};

}  // namespace stereo_ground_dem
