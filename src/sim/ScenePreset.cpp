#include "stereo_ground_dem/sim/ScenePreset.hpp"

#include <cmath>

namespace stereo_ground_dem::sim {

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kLane = 1.875;  // half of the 7.5 m two-lane road: the right lane's centre

BoxObstacle box(double x, double y, double yaw, double l, double w, double h, double vx,
                double vy = 0.0) {
  BoxObstacle b;
  b.center_xy = {x, y};
  b.yaw_rad = yaw;
  b.length_m = l;
  b.width_m = w;
  b.height_m = h;
  b.velocity_xy = {vx, vy};
  return b;
}

PoleObstacle pole(double x, double y, double r, double h) {
  PoleObstacle p;
  p.xy = {x, y};
  p.radius_m = r;
  p.height_m = h;
  return p;
}

// A road path whose centreline passes through (0, y0) heading along +x at s = 0: `back` metres of
// straight road behind, then `pieces`.
RoadPathOptions pathFromOrigin(double y0, double back, const std::vector<RoadPiece>& pieces) {
  RoadPathOptions p;
  p.anchor_xy_m = {0.0, y0};
  p.anchor_heading_rad = 0.0;
  p.start_s_m = -back;
  p.pieces.push_back({back, 0.0});
  p.pieces.insert(p.pieces.end(), pieces.begin(), pieces.end());
  return p;
}

// Guardrail boxes (0.3 m thick, 0.75 m high) along the road path at offset n(s) from s0 to s1:
// each box spans the chord between two points `step` apart.
template <typename OffsetFn>
void addGuardrail(const RoadPathOptions& options, double s0, double s1, double step, OffsetFn n,
                  std::vector<BoxObstacle>* boxes) {
  const RoadPath path(options);
  for (double s = s0; s + step <= s1 + 1e-9; s += step) {
    const RoadPath::Pose a = path.poseAt(s), b = path.poseAt(s + step);
    const Eigen::Vector2d pa = a.xy + n(s) * a.normal();
    const Eigen::Vector2d pb = b.xy + n(s + step) * b.normal();
    const Eigen::Vector2d c = 0.5 * (pa + pb);
    const Eigen::Vector2d dir = pb - pa;
    // A little longer than the chord so that neighbouring boxes meet on the outside of the curve.
    boxes->push_back(box(c.x(), c.y(), std::atan2(dir.y(), dir.x()), dir.norm() + 0.05, 0.3, 0.75, 0.0));
  }
}

}  // namespace

ScenePreset ScenePreset::forKind(SceneKind kind, uint64_t seed) {
  ScenePreset p;
  SceneOptions& o = p.scene;
  SequenceOptions& q = p.sequence;
  o.kind = kind;
  o.seed = seed;
  q.noise_seed = seed;
  switch (kind) {
    // --- the three standard scenes (unchanged): driven along y = 0 ---
    case SceneKind::kFlatRoad:
      break;
    case SceneKind::kBumpAndCurb:
      o.bump_enabled = true;
      o.curb_enabled = true;
      break;
    case SceneKind::kOffRoad:
      o.rolling_enabled = true;
      o.ruts_enabled = true;
      o.terrace_enabled = true;
      o.embankment_enabled = true;
      break;

    // --- crest / sag: +-4 % turning to -+4 % over a 60 m parabolic vertical curve that starts
    // 10 m ahead; level far behind and far ahead (so that heights stay bounded); the bump scene's
    // speed bump (on the vertical curve) and curb.
    case SceneKind::kCrest:
    case SceneKind::kSag: {
      const double g = kind == SceneKind::kCrest ? 0.04 : -0.04;
      o.profile_curves = {{-70.0, 40.0, g}, {10.0, 60.0, -g}, {150.0, 60.0, 0.0}};
      o.bump_enabled = true;
      o.bump_center_x_m = 30.0;
      o.curb_enabled = true;
      q.start_xy_m = {0.0, -kLane};
      break;
    }

    // --- banked_curve: a left curve of radius 120 m (the centreline; a full circle), driven in the
    // right (outer) lane from frame 0; 5 % superelevation rising to the outside over the road and
    // shoulders, flattening out over 4 m beyond.
    case SceneKind::kBankedCurve: {
      const double radius = 120.0;
      o.road_path.anchor_xy_m = {0.0, kLane};
      o.road_path.anchor_heading_rad = 0.0;
      o.road_path.start_s_m = -100.0;
      o.road_path.pieces = {{2.0 * M_PI * radius, 1.0 / radius}};
      o.bank_enabled = true;
      o.bank_center_xy_m = {0.0, kLane + radius};
      o.bank_radius_m = radius;
      o.bank_superelevation = 0.05;
      o.bank_half_width_m = 0.5 * o.road_width_m + o.shoulder_width_m;
      o.bank_transition_m = 4.0;
      q.follow_road_path = true;
      q.path_offset_m = -kLane;
      break;
    }

    // --- bounce: a rough dirt track at 0.75 m/frame: transverse bumps 4 cm high every 2.7 m (the
    // wheelbase: the body heaves), gentle rolling ground, potholes beside the wheel tracks, and a
    // body that pitches (+-1 deg) and rolls (+-0.7 deg) alternately from frame to frame, so that
    // consecutive frames differ by about 2 deg of pitch and 1.4 deg of roll (2.2-2.7 deg in all).
    case SceneKind::kBounce: {
      o.rolling_enabled = true;
      o.rolling_amplitude_m = 0.05;
      o.rolling_components = 2;
      o.rolling_min_wavelength_m = 30.0;
      o.rolling_max_wavelength_m = 60.0;
      o.transverse_waves = {{-10.0, 2.7, 85, 0.04}};  // both axles on it from frame 0
      const double holes[][5] = {
          {6.0, 1.7, 0.9, 0.7, 0.08},   {11.5, -1.8, 1.2, 0.8, 0.10}, {17.0, 1.9, 0.8, 0.9, 0.07},
          {23.0, -1.6, 1.0, 0.6, 0.09}, {29.5, 2.0, 1.3, 0.9, 0.10},  {36.0, -1.9, 0.9, 0.8, 0.08},
          {42.0, 1.7, 1.1, 0.7, 0.09},  {49.0, -1.7, 1.0, 0.9, 0.10}, {56.0, 1.8, 0.9, 0.8, 0.08},
          {63.0, -1.8, 1.2, 0.7, 0.09}};
      for (const auto& h : holes) {
        Pothole ph;
        ph.center_xy = {h[0], h[1]};
        ph.length_x_m = h[2];
        ph.width_y_m = h[3];
        ph.depth_m = h[4];
        o.potholes.push_back(ph);
      }
      q.speed_m_per_frame = 0.75;
      q.attitude_pitch_rad = 1.0 * kDeg;
      q.attitude_roll_rad = 0.7 * kDeg;
      q.attitude_jitter_rad = 0.1 * kDeg;
      break;
    }

    // --- tight_curve: a right curve driven from the first frame, the right (inner) lane on a
    // 22 m radius (1 m/frame: 2.6 deg of yaw per frame), 270 degrees of it, then straight.
    case SceneKind::kTightCurve: {
      const double lane_radius = 22.0;
      const double radius = lane_radius + kLane;
      o.road_path = pathFromOrigin(kLane, 60.0, {{1.5 * M_PI * radius, -1.0 / radius}, {300.0, 0.0}});
      q.follow_road_path = true;
      q.path_offset_m = -kLane;
      break;
    }

    // --- ramp: a highway on-ramp: one 4 m lane on a right curve of radius 90 m (1 m/frame), a
    // hatched gore on its left narrowing from 8 m to nothing over 80 m, the two-lane carriageway
    // beyond it, grass verges, guardrails on both outer edges, a 2.5 % grade.
    case SceneKind::kRamp: {
      const double radius = 90.0;
      o.road_path = pathFromOrigin(0.0, 60.0, {{0.5 * M_PI * radius, -1.0 / radius}, {300.0, 0.0}});
      o.road_width_m = 4.0;
      o.shoulder_width_m = 1.5;
      o.centre_line_enabled = false;
      o.gore_enabled = true;
      o.gore_start_s_m = 0.0;
      o.gore_end_s_m = 80.0;
      o.gore_start_width_m = 8.0;
      o.gore_end_width_m = 0.0;
      o.gore_lane_width_m = 7.5;
      o.hatch_period_m = 3.0;
      o.hatch_width_m = 0.6;
      o.profile_curves = {{-60.0, 40.0, 0.025}, {200.0, 60.0, 0.0}};
      const double half = 0.5 * o.road_width_m;
      auto right = [half](double) { return -(half + 1.0); };
      const SceneOptions& so = o;
      auto left = [half, &so](double s) {
        const double u = std::min(1.0, std::max(0.0, (s - so.gore_start_s_m) / (so.gore_end_s_m - so.gore_start_s_m)));
        const double gore = so.gore_start_width_m + u * (so.gore_end_width_m - so.gore_start_width_m);
        return half + gore + so.gore_lane_width_m + 1.0;
      };
      addGuardrail(o.road_path, -20.0, 220.0, 4.0, right, &o.boxes);
      addGuardrail(o.road_path, -20.0, 220.0, 4.0, left, &o.boxes);
      q.follow_road_path = true;
      break;
    }

    // --- rolling: off-road rolling terrain along x, vertical curves end to end (the same hills for
    // every seed): a dip, a climb steepening to 14 %, a crest 2.4 m up at x = 42 m, a descent
    // steepening to 15 %, a valley, a gentle rise; two seeded rolling components across it,
    // wheel ruts, and a 35 cm deep, 5 m wide ditch across the track 14 m ahead; dirt and grass.
    case SceneKind::kRolling:
      o.profile_curves = {{-30.0, 30.0, -0.04}, {0.0, 25.0, 0.14},  {25.0, 35.0, -0.15},
                          {60.0, 30.0, 0.06},   {90.0, 30.0, 0.0}};
      o.rolling_enabled = true;
      o.rolling_amplitude_m = 0.5;
      o.rolling_components = 2;
      o.rolling_min_wavelength_m = 25.0;
      o.rolling_max_wavelength_m = 60.0;
      o.ruts_enabled = true;
      o.transverse_waves = {{14.0, 5.0, 1, -0.35}};
      break;

    // --- shadows: a wide (4 lanes, 14 m), low-texture asphalt road (30 % of the usual texture
    // contrast) under a low sun from the front left; cars ahead, overtaking and oncoming, a truck,
    // and tall poles on the left whose shadows cross the road; cast shadows on.
    case SceneKind::kShadows: {
      o.road_width_m = 14.0;
      o.shoulder_width_m = 1.5;
      o.texture_contrast = 0.3;
      o.cast_shadows = true;
      o.sun_elevation_rad = 25.0 * kDeg;
      o.sun_azimuth_rad = 60.0 * kDeg;
      o.ambient = 0.3;
      const double lane = -5.25;  // the rightmost of the four 3.5 m lanes
      o.boxes = {
          box(14.0, lane, 0.0, 4.2, 1.8, 1.5, 12.0),    // ahead in our lane, a little faster
          box(-12.0, -1.75, 0.0, 4.4, 1.8, 1.5, 16.0),  // overtaking us in the next lane
          box(30.0, -1.75, 0.0, 8.0, 2.4, 3.0, 9.0),    // a truck ahead in the next lane
          box(70.0, 1.75, M_PI, 4.2, 1.8, 1.5, -12.0),  // oncoming
          box(40.0, 5.25, M_PI, 4.6, 1.9, 1.6, -10.0),  // oncoming, far lane
          box(110.0, 5.25, M_PI, 4.2, 1.8, 1.5, -11.0),
      };
      for (double x = 5.0; x < 200.0; x += 15.0) o.poles.push_back(pole(x, 8.5, 0.12, 6.0));
      q.start_xy_m = {0.0, lane};
      break;
    }

    // --- traffic: a two-lane street: a car ahead in our lane (11 m/s, we drive 10), a car
    // crossing the road 50 m ahead, oncoming cars, cars parked on the right shoulder, poles on
    // both sides; cast shadows on (sun from the back left).
    case SceneKind::kTraffic: {
      o.shoulder_width_m = 2.5;
      o.cast_shadows = true;
      o.sun_elevation_rad = 35.0 * kDeg;
      o.sun_azimuth_rad = 120.0 * kDeg;
      o.ambient = 0.35;
      o.boxes = {
          box(12.0, -kLane, 0.0, 4.2, 1.8, 1.5, 11.0),            // ahead in our lane
          box(50.0, 20.0, 0.5 * M_PI, 4.4, 1.8, 1.5, 0.0, -9.0),  // crossing from the left
          box(60.0, kLane, M_PI, 4.2, 1.8, 1.5, -10.0),           // oncoming
          box(110.0, kLane, M_PI, 4.6, 1.9, 1.6, -12.0),          // oncoming
          box(20.0, -5.0, 0.0, 4.2, 1.8, 1.5, 0.0),               // parked
          box(27.0, -5.0, 0.02, 4.0, 1.7, 1.45, 0.0),             // parked
          box(41.0, -5.1, -0.03, 4.5, 1.9, 1.55, 0.0),            // parked
          box(55.0, -5.1, 0.0, 5.2, 2.0, 2.1, 0.0),               // parked van
      };
      for (double x = 10.0; x < 120.0; x += 20.0) o.poles.push_back(pole(x, -6.8, 0.12, 5.0));
      o.poles.push_back(pole(25.0, 5.6, 0.15, 4.0));
      o.poles.push_back(pole(62.0, 5.6, 0.15, 4.0));
      q.start_xy_m = {0.0, -kLane};
      break;
    }
  }
  return p;
}

}  // namespace stereo_ground_dem::sim
