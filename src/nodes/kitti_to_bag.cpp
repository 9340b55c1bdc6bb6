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
//   --generic-16u FRAMES   images as 16UC1 big-endian (grey * 257): a depth-style encoding
//   --mono16-be FRAMES     images as mono16 big-endian (grey * 257): valid, byte-swapped by the node
//   --nan-info FRAMES      NaN in the left camera_info's P[2] (cx)
//   --inconsistent-info FRAMES  right camera_info with fx 1 % larger than the left
//   --change-info-from FRAME    from this frame on cx and cy are 2 px larger (a new calibration)
//   --unsync FRAMES        right image and camera_info stamped 30 ms later (never synchronize exactly)
//   --black FRAMES, --saturated FRAMES   images all 0 / all 255
//   --duplicate-stamp FRAMES   header stamps equal to the previous frame's
//   --stamp-offset FRAME:SECONDS[,...]  header stamps of one frame shifted (out of order)
//   --time-shift FRAME:SECONDS  header stamps of this and every later frame shifted (a clock jump)
// Bag (record) times stay the original, increasing ones: a defective stamp arrives in its place.
#include <ros/time.h>
#include <rosbag/bag.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2_msgs/TFMessage.h>

#include <boost/make_shared.hpp>
#include <map>
#include <set>
#include <sstream>

#include <cmath>
#include <limits>
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
    "  --drop FRAMES      nothing for these frames (a gap)\n"
    "  --generic-16u FRAMES  images as 16UC1 big-endian\n"
    "  --mono16-be FRAMES images as mono16 big-endian (valid)\n"
    "  --nan-info FRAMES  NaN in the left camera_info P\n"
    "  --inconsistent-info FRAMES  right camera_info fx 1 % larger\n"
    "  --change-info-from FRAME  cx, cy 2 px larger from this frame on\n"
    "  --unsync FRAMES    right image and camera_info stamped 30 ms later\n"
    "  --black FRAMES, --saturated FRAMES  images all 0 / all 255\n"
    "  --duplicate-stamp FRAMES  stamps equal to the previous frame's\n"
    "  --stamp-offset FRAME:SECONDS[,...]  stamps of one frame shifted\n"
    "  --time-shift FRAME:SECONDS  stamps of this and later frames shifted\n";

struct Args {
  std::string sequence, out, ns = "stereo", frame_id = "left_camera_optical";
  int frames = -1;
  double start_time = 1e9;
  double clock_hz = 100.0;
  bool static_tf = false;
  std::string base_frame = "base_link";
  double camera_height = 1.65;
  std::set<int> bad_size, bad_encoding, drop_info, drop, generic_16u, mono16_be, nan_info, inconsistent_info, unsync,
      black, saturated, duplicate_stamp;
  int change_info_from = -1;
  std::map<int, double> stamp_offset;
  int time_shift_from = -1;
  double time_shift_s = 0.0;
};

std::map<int, double> frameOffsets(const std::string& flag, const std::string& text) {
  std::map<int, double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const size_t colon = item.find(':');
    char* end = nullptr;
    const long f = colon == std::string::npos ? -1 : std::strtol(item.substr(0, colon).c_str(), &end, 10);
    const std::string value = colon == std::string::npos ? "" : item.substr(colon + 1);
    char* vend = nullptr;
    const double v = std::strtod(value.c_str(), &vend);
    if (f < 0 || *end != '\0' || value.empty() || *vend != '\0' || !std::isfinite(v)) {
      throw std::invalid_argument(flag + " expects FRAME:SECONDS like 5:-0.03, got '" + text + "'");
    }
    out[static_cast<int>(f)] = v;
  }
  return out;
}

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
    else if (k == "--generic-16u") a.generic_16u = frameList(k, value());
    else if (k == "--mono16-be") a.mono16_be = frameList(k, value());
    else if (k == "--nan-info") a.nan_info = frameList(k, value());
    else if (k == "--inconsistent-info") a.inconsistent_info = frameList(k, value());
    else if (k == "--change-info-from") a.change_info_from = static_cast<int>(number(k, value()));
    else if (k == "--unsync") a.unsync = frameList(k, value());
    else if (k == "--black") a.black = frameList(k, value());
    else if (k == "--saturated") a.saturated = frameList(k, value());
    else if (k == "--duplicate-stamp") a.duplicate_stamp = frameList(k, value());
    else if (k == "--stamp-offset") a.stamp_offset = frameOffsets(k, value());
    else if (k == "--time-shift") {
      const std::map<int, double> m = frameOffsets(k, value());
      if (m.size() != 1) throw std::invalid_argument("--time-shift takes one FRAME:SECONDS");
      a.time_shift_from = m.begin()->first;
      a.time_shift_s = m.begin()->second;
    }
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

/// An 8-bit grey (or colour, converted to grey) image as 16 bits (grey * 257), big-endian bytes.
sensor_msgs::Image toImage16BigEndian(const cv::Mat& in, const std_msgs::Header& header, const std::string& encoding) {
  cv::Mat grey = in;
  if (in.channels() == 3) cv::cvtColor(in, grey, cv::COLOR_BGR2GRAY);
  if (in.channels() == 4) cv::cvtColor(in, grey, cv::COLOR_BGRA2GRAY);
  if (grey.depth() != CV_8U) throw std::runtime_error("--generic-16u / --mono16-be need 8-bit images");
  sensor_msgs::Image img;
  img.header = header;
  img.height = static_cast<uint32_t>(grey.rows);
  img.width = static_cast<uint32_t>(grey.cols);
  img.encoding = encoding;
  img.is_bigendian = 1;
  img.step = img.width * 2;
  img.data.resize(static_cast<size_t>(img.step) * img.height);
  for (int r = 0; r < grey.rows; ++r)
    for (int c = 0; c < grey.cols; ++c) {
      const unsigned v = grey.at<uint8_t>(r, c) * 257u;
      img.data[static_cast<size_t>(r) * img.step + 2 * c] = static_cast<uint8_t>(v >> 8);
      img.data[static_cast<size_t>(r) * img.step + 2 * c + 1] = static_cast<uint8_t>(v & 0xff);
    }
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
  ros::Time previous_stamp;
  for (int i = 0; i < n; ++i) {
    if (a.drop.count(i)) continue;
    ++written;
    cv::Mat left, right;
    seq.read(i, &left, &right);
    const double t = a.start_time + (seq.stamp(i) - t0);
    clockUpTo(t);
    const ros::Time record_time(t);  // bag order: always the original, increasing time
    std_msgs::Header h;
    h.seq = static_cast<uint32_t>(i);
    double stamp = t;
    if (a.time_shift_from >= 0 && i >= a.time_shift_from) stamp += a.time_shift_s;
    if (a.stamp_offset.count(i)) stamp += a.stamp_offset.at(i);
    h.stamp = a.duplicate_stamp.count(i) && !previous_stamp.isZero() ? previous_stamp : ros::Time(stamp);
    previous_stamp = h.stamp;
    h.frame_id = a.frame_id;
    if (a.black.count(i)) left.setTo(0), right.setTo(0);
    if (a.saturated.count(i)) left.setTo(255), right.setTo(255);
    StereoRig r = rig;
    r.width = left.cols;
    r.height = left.rows;
    if (a.change_info_from >= 0 && i >= a.change_info_from) r.cx += 2.0, r.cy += 2.0;
    std_msgs::Header hr = h;
    if (a.unsync.count(i)) hr.stamp += ros::Duration(0.03);
    sensor_msgs::Image li = toImage(left, h), ri;
    StereoRig rr = r;
    if (a.inconsistent_info.count(i)) rr.fx *= 1.01;
    sensor_msgs::CameraInfo lci = toInfo(r, 0.0, h), rci = toInfo(rr, -rr.fx * r.baseline_m, hr);
    if (a.nan_info.count(i)) lci.P[2] = std::numeric_limits<double>::quiet_NaN();
    if (a.bad_size.count(i)) {
      ri = toImage(right(cv::Rect(0, 0, right.cols - 1, right.rows)).clone(), hr);
      rci.width -= 1;
    } else {
      ri = toImage(right, hr);
    }
    if (a.bad_encoding.count(i)) li.encoding = ri.encoding = sensor_msgs::image_encodings::BAYER_RGGB8;
    if (a.generic_16u.count(i) || a.mono16_be.count(i)) {
      const std::string e = a.generic_16u.count(i) ? sensor_msgs::image_encodings::TYPE_16UC1
                                                   : sensor_msgs::image_encodings::MONO16;
      li = toImage16BigEndian(left, h, e);
      ri = toImage16BigEndian(right, hr, e);
    }
    bag.write(a.ns + "/left/image_rect", record_time, li);
    if (!a.drop_info.count(i)) bag.write(a.ns + "/left/camera_info", record_time, lci);
    bag.write(a.ns + "/right/image_rect", record_time, ri);
    bag.write(a.ns + "/right/camera_info", record_time, rci);
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
