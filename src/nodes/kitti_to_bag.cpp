// kitti_to_bag: a KITTI-odometry-style folder (the layout KittiSequence reads, e.g.
// data/kitti_seq06_sample or what sgd_render writes) to a rosbag that stereo_ground_dem's launch
// files replay: rectified images and camera_info of both cameras, and /clock.
//
//   kitti_to_bag --sequence DIR --out FILE.bag [options]
//
// Topics (NS = --namespace, default "stereo"): /NS/left/image_rect, /NS/left/camera_info,
// /NS/right/image_rect, /NS/right/camera_info (mono8, mono16 or bgr8 as the PNGs are), /clock.
// Stamps: --start-time + times.txt (or index * 0.1 s). camera_info: P from calib.txt (right
// P(0,3) = -fx * baseline), K the same intrinsics, R identity, no distortion (rectified).
// --static-tf adds a latched /tf_static base_link -> camera (camera --camera-height above
// base_link, looking along its x axis, optical axes: z forward, x right, y down).
//
// Test bags with defects (FRAMES is a comma-separated list of frame indices):
//   --bad-size FRAMES      right image one column narrower than the left (and its camera_info)
//   --bad-encoding FRAMES  both images labelled bayer_rggb8
//   --drop-info FRAMES     no left camera_info for these frames (the pair never synchronizes)
//   --drop FRAMES          nothing at all for these frames (a gap of dropped frames)
#include <ros/time.h>
#include <rosbag/bag.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2_msgs/TFMessage.h>

#include <boost/make_shared.hpp>
#include <set>
#include <sstream>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "stereo_ground_dem/io/KittiSequence.hpp"

using stereo_ground_dem::KittiSequence;
using stereo_ground_dem::StereoRig;

namespace {

const char* kUsage =
    "usage: kitti_to_bag --sequence DIR --out FILE.bag [options]\n"
    "  --frames N         first N frames only\n"
    "  --namespace NS     topic namespace (default stereo): /NS/left/image_rect, /NS/left/camera_info, ...\n"
    "  --frame-id F       header.frame_id of images and camera_info (default left_camera_optical)\n"
    "  --start-time S     stamp of time 0 of times.txt [s since the epoch] (default 1000000000)\n"
    "  --clock-hz H       /clock messages per second of bag time (default 100; 0: none)\n"
    "  --static-tf        write /tf_static BASE -> frame-id (camera CAMERA_HEIGHT above BASE, optical axes)\n"
    "  --base-frame BASE  (default base_link)\n"
    "  --camera-height H  [m] (default 1.65, KITTI)\n"
    "  --bad-size FRAMES  right image and camera_info one column narrower (FRAMES: 3,4,7)\n"
    "  --bad-encoding FRAMES  images labelled bayer_rggb8\n"
    "  --drop-info FRAMES no left camera_info for these frames\n"
    "  --drop FRAMES      nothing for these frames (a gap)\n";

struct Args {
  std::string sequence, out, ns = "stereo", frame_id = "left_camera_optical";
  int frames = -1;
  double start_time = 1e9;
  double clock_hz = 100.0;
  bool static_tf = false;
  std::string base_frame = "base_link";
  double camera_height = 1.65;
  std::set<int> bad_size, bad_encoding, drop_info, drop;
};

std::set<int> frameList(const std::string& flag, const std::string& text) {
  std::set<int> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v < 0) throw std::invalid_argument(flag + " expects frame indices like 3,4,7, got '" + text + "'");
    out.insert(static_cast<int>(v));
  }
  return out;
}

double number(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v)) throw std::invalid_argument(flag + " expects a number, got '" + text + "'");
  return v;
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(k + " needs a value");
      return argv[++i];
    };
    if (k == "--sequence") a.sequence = value();
    else if (k == "--out") a.out = value();
    else if (k == "--frames") {
      const double n = number(k, value());
      if (n < 1 || n != std::floor(n)) throw std::invalid_argument("--frames needs a positive integer");
      a.frames = static_cast<int>(n);
    } else if (k == "--namespace") a.ns = value();
    else if (k == "--frame-id") a.frame_id = value();
    else if (k == "--start-time") a.start_time = number(k, value());
    else if (k == "--clock-hz") a.clock_hz = number(k, value());
    else if (k == "--static-tf") a.static_tf = true;
    else if (k == "--base-frame") a.base_frame = value();
    else if (k == "--camera-height") a.camera_height = number(k, value());
    else if (k == "--bad-size") a.bad_size = frameList(k, value());
    else if (k == "--bad-encoding") a.bad_encoding = frameList(k, value());
    else if (k == "--drop-info") a.drop_info = frameList(k, value());
    else if (k == "--drop") a.drop = frameList(k, value());
    else if (k == "-h" || k == "--help") {
      std::cout << kUsage;
      std::exit(0);
    } else {
      throw std::invalid_argument("unknown argument '" + k + "'");
    }
  }
  if (a.sequence.empty() || a.out.empty()) throw std::invalid_argument("--sequence and --out are required");
  if (a.start_time <= 0.0) throw std::invalid_argument("--start-time must be > 0 (ROS time 0 means 'no stamp')");
  if (a.clock_hz < 0.0) throw std::invalid_argument("--clock-hz must be >= 0");
  while (!a.ns.empty() && a.ns.back() == '/') a.ns.pop_back();
  if (!a.ns.empty() && a.ns.front() != '/') a.ns = "/" + a.ns;
  return a;
}

sensor_msgs::Image toImage(const cv::Mat& in, const std_msgs::Header& header) {
  cv::Mat m = in;
  std::string encoding;
  switch (m.type()) {
    case CV_8UC1: encoding = sensor_msgs::image_encodings::MONO8; break;
    case CV_16UC1: encoding = sensor_msgs::image_encodings::MONO16; break;
    case CV_8UC3: encoding = sensor_msgs::image_encodings::BGR8; break;
    case CV_8UC4:
      cv::cvtColor(in, m, cv::COLOR_BGRA2BGR);
      encoding = sensor_msgs::image_encodings::BGR8;
      break;
    default: throw std::runtime_error("unsupported image type " + std::to_string(m.type()));
  }
  sensor_msgs::Image img;
  img.header = header;
  img.height = static_cast<uint32_t>(m.rows);
  img.width = static_cast<uint32_t>(m.cols);
  img.encoding = encoding;
  img.is_bigendian = 0;
  img.step = static_cast<uint32_t>(m.cols * m.elemSize());
  img.data.resize(static_cast<size_t>(img.step) * img.height);
  for (int r = 0; r < m.rows; ++r) std::copy_n(m.ptr<uint8_t>(r), img.step, img.data.data() + static_cast<size_t>(r) * img.step);
  return img;
}

sensor_msgs::CameraInfo toInfo(const StereoRig& rig, double tx_px, const std_msgs::Header& header) {
  sensor_msgs::CameraInfo c;
  c.header = header;
  c.width = static_cast<uint32_t>(rig.width);
  c.height = static_cast<uint32_t>(rig.height);
  c.distortion_model = "plumb_bob";
  c.D.assign(5, 0.0);
  c.K = {rig.fx, 0.0, rig.cx, 0.0, rig.fy, rig.cy, 0.0, 0.0, 1.0};
  c.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  c.P = {rig.fx, 0.0, rig.cx, tx_px, 0.0, rig.fy, rig.cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  return c;
}

int run(const Args& a) {
  const KittiSequence seq = KittiSequence::open(a.sequence);
  const int n = a.frames > 0 ? std::min(a.frames, seq.size()) : seq.size();
  if (n == 0) throw std::runtime_error("no frames in '" + a.sequence + "'");
  const StereoRig& rig = seq.rig();
  rosbag::Bag bag(a.out, rosbag::bagmode::Write);
  const double t0 = seq.stamp(0);
  double next_clock = a.start_time;
  auto clockUpTo = [&](double t) {
    if (a.clock_hz <= 0.0) return;
    while (next_clock <= t + 1e-9) {
      rosgraph_msgs::Clock c;
      c.clock = ros::Time(next_clock);
      bag.write("/clock", c.clock, c);
      next_clock += 1.0 / a.clock_hz;
    }
  };
  if (a.static_tf) {
    geometry_msgs::TransformStamped t;
    t.header.stamp = ros::Time(a.start_time);
    t.header.frame_id = a.base_frame;
    t.child_frame_id = a.frame_id;
    t.transform.translation.z = a.camera_height;
    // columns of base_R_optical: optical x = -base y, optical y = -base z, optical z = base x
    t.transform.rotation.x = -0.5;
    t.transform.rotation.y = 0.5;
    t.transform.rotation.z = -0.5;
    t.transform.rotation.w = 0.5;
    tf2_msgs::TFMessage m;
    m.transforms.push_back(t);
    auto header = boost::make_shared<ros::M_string>();
    // rosbag stores a given connection header as it is: it must describe the type as well
    (*header)["type"] = ros::message_traits::datatype(m);
    (*header)["md5sum"] = ros::message_traits::md5sum(m);
    (*header)["message_definition"] = ros::message_traits::definition(m);
    (*header)["topic"] = "/tf_static";
    (*header)["latching"] = "1";
    (*header)["callerid"] = "/kitti_to_bag";
    bag.write("/tf_static", t.header.stamp, m, header);
  }
  int written = 0;
  for (int i = 0; i < n; ++i) {
    if (a.drop.count(i)) continue;
    ++written;
    cv::Mat left, right;
    seq.read(i, &left, &right);
    const double t = a.start_time + (seq.stamp(i) - t0);
    clockUpTo(t);
    std_msgs::Header h;
    h.seq = static_cast<uint32_t>(i);
    h.stamp = ros::Time(t);
    h.frame_id = a.frame_id;
    StereoRig r = rig;
    r.width = left.cols;
    r.height = left.rows;
    sensor_msgs::Image li = toImage(left, h), ri;
    sensor_msgs::CameraInfo rci = toInfo(r, -r.fx * r.baseline_m, h);
    if (a.bad_size.count(i)) {
      ri = toImage(right(cv::Rect(0, 0, right.cols - 1, right.rows)).clone(), h);
      rci.width -= 1;
    } else {
      ri = toImage(right, h);
    }
    if (a.bad_encoding.count(i)) li.encoding = ri.encoding = sensor_msgs::image_encodings::BAYER_RGGB8;
    bag.write(a.ns + "/left/image_rect", h.stamp, li);
    if (!a.drop_info.count(i)) bag.write(a.ns + "/left/camera_info", h.stamp, toInfo(r, 0.0, h));
    bag.write(a.ns + "/right/image_rect", h.stamp, ri);
    bag.write(a.ns + "/right/camera_info", h.stamp, rci);
  }
  bag.close();
  std::printf("wrote %d stereo frames (%dx%d, baseline %.4f m) to %s: %s/{left,right}/{image_rect,camera_info}%s%s\n",
              written, rig.width, rig.height, rig.baseline_m, a.out.c_str(), a.ns.c_str(),
              a.clock_hz > 0.0 ? ", /clock" : "", a.static_tf ? ", /tf_static" : "");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  ros::Time::init();
  Args a;
  try {
    a = parse(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kitti_to_bag: %s\n%s", e.what(), kUsage);
    return 2;
  }
  try {
    return run(a);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kitti_to_bag: %s\n", e.what());
    return 1;
  }
}
