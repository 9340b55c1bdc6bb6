#include "stereo_ground_dem/ros/DemServices.hpp"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <sstream>

#include "stereo_ground_dem/io/DemExporter.hpp"
#include "stereo_ground_dem/io/MapStateFile.hpp"
#include "stereo_ground_dem/ros/HeightGridConverter.hpp"
#include "stereo_ground_dem/ros/MapWindowSampler.hpp"

namespace stereo_ground_dem {

namespace {
std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + v[i];
  return s;
}
}  // namespace

DemServices::DemServices(DemWorker& worker, const RosNodeOptions& options, const TraversabilityOptions& traversability,
                         const std::string& node_name)
    : worker_(worker), options_(options), node_name_(node_name), traversability_(traversability) {}

void DemServices::advertise(ros::NodeHandle& mt_pnh) {
  srv_reset_ = mt_pnh.advertiseService("reset", &DemServices::reset, this);
  srv_save_ = mt_pnh.advertiseService("save_map", &DemServices::saveMap, this);
  srv_submap_ = mt_pnh.advertiseService("get_submap", &DemServices::getSubmap, this);
  srv_load_ = mt_pnh.advertiseService("load_map", &DemServices::loadMap, this);
}

void DemServices::shutdown() {
  srv_reset_.shutdown();
  srv_save_.shutdown();
  srv_submap_.shutdown();
  srv_load_.shutdown();
}

void DemServices::setTraversability(const TraversabilityOptions& options) {
  std::lock_guard<std::mutex> lock(mutex_);
  traversability_ = options;
}

TraversabilityOptions DemServices::traversability() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return traversability_;
}

bool DemServices::reset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  const bool pending = worker_.optionsPending();
  worker_.requestReset("~reset service", false);
  res.success = true;
  res.message = pending ? "map reset; pending parameter changes applied" : "map reset";
  return true;
}

bool DemServices::saveMap(SaveMap::Request& req, SaveMap::Response& res) {
  const std::string dir = req.directory.empty() ? options_.save_directory : req.directory;
  const std::shared_ptr<const MapSnapshot> snap = worker_.snapshot();
  if (!snap->map) {
    res.success = false;
    res.message = "nothing to save: no stereo frame has been mapped yet";
    return true;
  }
  const MapWindowSampler sampler(traversability());
  const DemLayers d = sampler.sample(*snap->map, snap->map->knownBounds(), 0, {snap->ortho.get(), snap->residual.get()});
  DemExport dem;
  dem.grid = d.grid;
  dem.elevation = *d.find("elevation");
  dem.variance = *d.find("variance");
  dem.traversability = *d.find("traversability");
  if (const cv::Mat* o = d.find("obstacle")) dem.obstacles = *o;
  if (const cv::Mat* o = d.find("obstacle_height")) dem.obstacle_height = *o;
  if (const cv::Mat* o = d.find("intensity")) dem.intensity = *o;
  if (const cv::Mat* o = d.find("traversability_confidence")) dem.traversability_confidence = *o;
  if (const cv::Mat* o = d.find("residual")) dem.residual = *o;
  if (const cv::Mat* o = d.find("residual_outlier_rate")) dem.residual_outlier_rate = *o;
  if (snap->ortho) dem.ortho = snap->ortho->raster(&dem.ortho_grid);
  dem.ground_T_camera0 = snap->ground_T_camera0;
  dem.trajectory_xy = snap->trajectory_xy;
  dem.extra = {{"mode", "ROS node " + node_name_}, {"frame_id", options_.odom_frame}};
  try {
    const std::vector<std::string> names = DemExporter::write(dir, dem, req.pictures);
    char cwd[4096];
    const std::string base =
        dir.empty() || dir[0] == '/' ? dir : std::string(getcwd(cwd, sizeof(cwd)) ? cwd : ".") + "/" + dir;
    for (const std::string& n : names) res.files.push_back(n.empty() || n[0] == '/' ? n : base + "/" + n);
    if (snap->estimator) {  // what ~load_map (or dem_offline --resume) continues from
      SavedMapState state;
      state.estimator = *snap->estimator;
      state.trajectory_xy = snap->trajectory_xy;
      state.image_width_px = snap->image_width_px;
      state.image_height_px = snap->image_height_px;
      MapStateFile::write(dir + "/state", state, *snap->map, snap->ortho.get(), snap->residual.get());
      res.files.push_back(base + "/state");
    }
    res.success = true;
    res.message = "wrote " + std::to_string(res.files.size()) + " files to " + base;
  } catch (const std::exception& e) {
    res.success = false;
    res.message = e.what();
  }
  return true;
}

bool DemServices::loadMap(LoadMap::Request& req, LoadMap::Response& res) {
  const std::string dir = req.directory.empty() ? options_.save_directory : req.directory;
  auto done = worker_.requestLoad(dir);
  // the worker loads between frames (a frame takes ~0.2 s; a large map ~1 s to read)
  if (done.wait_for(std::chrono::seconds(10)) == std::future_status::ready) {
    const std::pair<bool, std::string> r = done.get();
    res.success = r.first;
    res.message = r.second;
  } else if (!worker_.hasCalibration()) {
    res.success = true;
    res.message = "queued: '" + dir + "' is loaded with the first stereo frame (no camera_info yet; diagnostics say how it went)";
  } else {
    res.success = false;
    res.message = "still loading '" + dir + "' after 10 s: diagnostics will say how it went";
  }
  return true;
}

bool DemServices::getSubmap(GetSubmap::Request& req, GetSubmap::Response& res) {
  if (!std::isfinite(req.center_x) || !std::isfinite(req.center_y) || !(req.length_x > 0.0) ||
      !(req.length_y > 0.0) || !std::isfinite(req.length_x) || !std::isfinite(req.length_y)) {
    res.success = false;
    res.message = "center must be finite and length_x, length_y > 0";
    return true;
  }
  const std::shared_ptr<const MapSnapshot> snap = worker_.snapshot();
  if (!snap->map) {
    res.success = false;
    res.message = "the map is empty: no stereo frame has been mapped yet (or since the last reset)";
    return true;
  }
  const ElevationMap& map = *snap->map;
  const GroundGrid w =
      MapWindowSampler::window(map.options().resolution_m, req.center_x, req.center_y, req.length_x, req.length_y);
  DemLayers d = MapWindowSampler(traversability()).sample(map, w, options_.global_map_max_cells,
                                                         {snap->ortho.get(), snap->residual.get()});
  if (!req.layers.empty()) {
    std::vector<GridLayer> chosen;
    std::vector<std::string> unknown;
    for (const std::string& name : req.layers) {
      const cv::Mat* m = d.find(name);
      if (m) chosen.push_back({name, *m});
      else unknown.push_back(name);
    }
    if (!unknown.empty()) {
      std::vector<std::string> names;
      for (const GridLayer& l : d.layers) names.push_back(l.name);
      res.success = false;
      res.message = "unknown layers " + joined(unknown) + " (available: " + joined(names) + ")";
      return true;
    }
    d.layers = chosen;
  }
  std_msgs::Header header;
  header.stamp = snap->stamp;
  header.frame_id = options_.odom_frame;
  res.map = HeightGridConverter::toMessage(d.grid, d.layers, header);
  res.success = true;
  std::ostringstream os;
  os << d.grid.cols << " x " << d.grid.rows << " cells of " << d.grid.resolution_m << " m, " << d.knownCount()
     << " known";
  res.message = os.str();
  return true;
}

}  // namespace stereo_ground_dem
