#include "stereo_ground_dem/sim/RayCaster.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace stereo_ground_dem::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kObstacleBuryM = 1.0;     // obstacles reach this far below the terrain
constexpr double kTerrainHitEpsM = 1e-7;   // a ray closer than this above the terrain hits it
constexpr int kMaxMarchSteps = 20000;
constexpr int kGridMinObstacles = 8;       // more static obstacles than this: ObstacleGrid
constexpr double kGridCellM = 4.0;

constexpr int kTerrainTop = SurfaceHit::kTerrainTop;
constexpr int kTerrainFaceX = SurfaceHit::kTerrainFaceX;
constexpr int kTerrainFaceY = SurfaceHit::kTerrainFaceY;
constexpr int kBoxFaceBase = SurfaceHit::kBoxFaceBase;
constexpr int kPoleSide = SurfaceHit::kPoleSide;
constexpr int kPoleTop = SurfaceHit::kPoleTop;

}  // namespace

RayCaster::RayCaster(std::shared_ptr<const TerrainModel> terrain, const SceneOptions& options)
    : terrain_(std::move(terrain)), options_(options) {
  int statics = static_cast<int>(options_.poles.size());
  double top = 0.0;
  for (size_t i = 0; i < options_.boxes.size(); ++i) {
    const BoxObstacle& b = options_.boxes[i];
    BoxCache bc;
    bc.moving = b.velocity_xy.x() != 0.0 || b.velocity_xy.y() != 0.0;
    bc.cos_yaw = std::cos(b.yaw_rad);
    bc.sin_yaw = std::sin(b.yaw_rad);
    bc.radius = 0.5 * std::hypot(b.length_m, b.width_m) + 1e-9;
    bc.terrain_z = terrain_->height(b.center_xy.x(), b.center_xy.y());
    box_cache_.push_back(bc);
    if (bc.moving) {
      moving_boxes_.push_back(static_cast<int>(i));
    } else {
      ++statics;
    }
    top = std::max(top, b.height_m);
  }
  for (const auto& p : options_.poles) {
    top = std::max(top, p.height_m);
    pole_terrain_z_.push_back(terrain_->height(p.xy.x(), p.xy.y()));
  }
  obstacle_z_lo_ = terrain_->minHeight() - kObstacleBuryM - 1e-6;
  obstacle_z_hi_ = terrain_->maxHeight() + top + 1e-6;
  if (statics > kGridMinObstacles) {
    std::vector<double> top_z;
    for (size_t i = 0; i < options_.boxes.size(); ++i) {
      top_z.push_back(box_cache_[i].terrain_z + options_.boxes[i].height_m);
    }
    for (size_t j = 0; j < options_.poles.size(); ++j) {
      top_z.push_back(pole_terrain_z_[j] + options_.poles[j].height_m);
    }
    grid_ = ObstacleGrid(options_, top_z, kGridCellM);
  }
}

int RayCaster::obstacleIdAt(double x, double y, double time_s) const {
  const auto& o = options_;
  if (!grid_.empty()) {
    thread_local std::vector<int> ids;
    ids.assign(moving_boxes_.begin(), moving_boxes_.end());
    grid_.collectAt(x, y, &ids);
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    for (int id : ids) {
      if (insideFootprint(id, x, y, time_s)) return id + 1;
    }
    return 0;
  }
  for (size_t i = 0; i < o.boxes.size(); ++i) {
    if (insideFootprint(static_cast<int>(i), x, y, time_s)) return static_cast<int>(i) + 1;
  }
  for (size_t j = 0; j < o.poles.size(); ++j) {
    if (insideFootprint(static_cast<int>(o.boxes.size() + j), x, y, time_s)) {
      return static_cast<int>(o.boxes.size() + j) + 1;
    }
  }
  return 0;
}

bool RayCaster::insideFootprint(int index, double x, double y, double time_s) const {
  const auto& o = options_;
  const auto nb = static_cast<int>(o.boxes.size());
  if (index < nb) {
    const BoxObstacle& b = o.boxes[static_cast<size_t>(index)];
    const Eigen::Vector2d c = b.centerAt(time_s);
    const BoxCache& bc = box_cache_[static_cast<size_t>(index)];
    const double cy = bc.cos_yaw, sy = bc.sin_yaw;
    const double lx = cy * (x - c.x()) + sy * (y - c.y());
    const double ly = -sy * (x - c.x()) + cy * (y - c.y());
    return std::abs(lx) <= 0.5 * b.length_m && std::abs(ly) <= 0.5 * b.width_m;
  }
  const PoleObstacle& p = o.poles[static_cast<size_t>(index - nb)];
  return (Eigen::Vector2d(x, y) - p.xy).squaredNorm() <= p.radius_m * p.radius_m;
}

double RayCaster::surfaceHeight(double x, double y, double time_s) const {
  const int id = obstacleIdAt(x, y, time_s);
  if (id <= 0) return terrain_->height(x, y);
  const auto nb = static_cast<int>(options_.boxes.size());
  if (id <= nb) {
    const BoxObstacle& b = options_.boxes[static_cast<size_t>(id - 1)];
    const Eigen::Vector2d c = b.centerAt(time_s);
    return terrain_->height(c.x(), c.y()) + b.height_m;
  }
  const PoleObstacle& p = options_.poles[static_cast<size_t>(id - nb - 1)];
  return terrain_->height(p.xy.x(), p.xy.y()) + p.height_m;
}

SurfaceHit RayCaster::intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                double t_max, double time_s) const {
  if (!grid_.empty()) {
    // Many obstacles: the terrain first, so that the obstacles' trace stops at its hit.
    const SurfaceHit terrain = intersectTerrain(o, d, t_max);
    const SurfaceHit obstacle = intersectObstacles(o, d, terrain.hit() ? terrain.t : t_max, time_s);
    return obstacle.hit() ? obstacle : terrain;
  }
  SurfaceHit best = intersectObstacles(o, d, t_max, time_s);
  const SurfaceHit terrain = intersectTerrain(o, d, best.hit() ? best.t : t_max);
  if (terrain.hit() && (!best.hit() || terrain.t < best.t)) best = terrain;
  return best;
}

SurfaceHit RayCaster::intersectTerrain(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                       double t_max) const {
  SurfaceHit none;
  const TerrainModel& terrain = *terrain_;
  const double z_max = terrain.maxHeight();
  double t_lo = 0.0;
  double t_hi = t_max;
  // Clip to the slab below z_max that contains all of the terrain.
  if (o.z() > z_max) {
    if (d.z() >= 0.0) return none;
    t_lo = (o.z() - z_max) / -d.z();
  } else if (d.z() > 0.0) {
    t_hi = std::min(t_hi, (z_max - o.z()) / d.z());
  }
  if (!(t_lo < t_hi)) return none;

  // Breakpoints: where the ray crosses a feature line, with the line's axis (-1: none), sorted.
  constexpr int kMaxBreakpoints = 160;  // more than the feature lines SceneOptions allows
  double bp_t[kMaxBreakpoints];
  int bp_axis[kMaxBreakpoints];
  int nbp = 0;
  bp_t[nbp] = t_lo;
  bp_axis[nbp++] = -1;
  auto addCrossings = [&](const std::vector<double>& lines, int axis) {
    const double oc = o[axis], dc = d[axis];
    if (dc == 0.0) return;
    const double inv = 1.0 / dc;
    for (double l : lines) {
      const double t = (l - oc) * inv;
      if (t > t_lo && t < t_hi && nbp < kMaxBreakpoints - 1) {
        // Insertion into the sorted list.
        int j = nbp++;
        while (j > 1 && bp_t[j - 1] > t) {
          bp_t[j] = bp_t[j - 1];
          bp_axis[j] = bp_axis[j - 1];
          --j;
        }
        bp_t[j] = t;
        bp_axis[j] = axis;
      }
    }
  };
  addCrossings(terrain.xLines(), 0);
  addCrossings(terrain.yLines(), 1);
  bp_t[nbp] = t_hi;
  bp_axis[nbp++] = -1;

  // Directional bounds of the features along this ray.
  const TerrainModel::RayBounds rb = terrain.rayBounds(d);
  for (int i = 0; i + 1 < nbp; ++i) {
    const double a = bp_t[i];
    const double b = bp_t[i + 1];
    if (!(b > a)) continue;
    const double tm = 0.5 * (a + b);
    const TerrainModel::Cell cell = terrain.cellAt(o.x() + tm * d.x(), o.y() + tm * d.y());
    // Bounds in this cell.
    double slope, curv, ztop, linear;
    terrain.cellBounds(rb, cell, &slope, &curv, &ztop, &linear);
    // The ray's rate of climb over the linear part of the terrain.
    const double dz_rel = d.z() - linear;

    double gx = 0.0, gy = 0.0;
    const double dz = d.z();
    double t = a;
    Eigen::Vector3d p;
    double f;
    const double za = o.z() + a * dz;
    if (za > ztop) {
      // Above everything in this cell: no face on entry; go down to the cell's top bound.
      if (dz >= 0.0) continue;
      t = a + (za - ztop) / -dz;
      if (t >= b) continue;
      p = o + t * d;
      f = p.z() - terrain.heightInCell(p.x(), p.y(), cell, &gx, &gy);
    } else {
      p = o + t * d;
      f = p.z() - terrain.heightInCell(p.x(), p.y(), cell, &gx, &gy);
      if (bp_axis[i] >= 0 && f < -1e-9) {
        // Below the terrain on entering the cell: the ray hits the vertical face on the line.
        SurfaceHit hit;
        hit.t = t;
        hit.point = p;
        hit.object_id = 0;
        const int axis = bp_axis[i];
        hit.normal = Eigen::Vector3d::Zero();
        hit.normal[axis] = d[axis] > 0.0 ? -1.0 : 1.0;
        hit.surface = axis == 0 ? kTerrainFaceX : kTerrainFaceY;
        return hit;
      }
    }
    // The ray rises at least as fast as the terrain can: no hit in this cell.
    if (f > kTerrainHitEpsM && dz_rel - slope >= 0.0) continue;
    bool hit_found = false;
    for (int it = 0; it < kMaxMarchSteps; ++it) {
      if (f <= kTerrainHitEpsM) {
        hit_found = true;
        break;
      }
      const double fd = dz - (gx * d.x() + gy * d.y());
      // Safe steps: f(t + s) >= f + (dz_rel - slope) s  and  f(t + s) >= f + fd s - curv s^2 / 2.
      const double s1 = slope - dz_rel > 0.0 ? f / (slope - dz_rel) : kInf;
      double s2;
      if (curv > 0.0) {
        s2 = (fd + std::sqrt(fd * fd + 2.0 * curv * f)) / curv;
      } else {
        s2 = fd >= 0.0 ? kInf : f / -fd;
      }
      const double s = std::max(s1, s2);
      if (t + s >= b) break;
      t += s;
      p = o + t * d;
      f = p.z() - terrain.heightInCell(p.x(), p.y(), cell, &gx, &gy);
      if (it + 1 == kMaxMarchSteps) hit_found = true;
    }
    if (hit_found) {
      SurfaceHit hit;
      hit.t = t;
      hit.point = p;
      hit.object_id = 0;
      hit.normal = Eigen::Vector3d(-gx, -gy, 1.0).normalized();
      hit.surface = kTerrainTop;
      return hit;
    }
  }
  return none;
}

SurfaceHit RayCaster::intersectObstacles(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                         double t_max, double time_s) const {
  SurfaceHit best;
  double t_best = t_max;
  const auto& so = options_;
  // Whether the ray's x-y trace on [0, t_best] passes within `radius` of `c` (cheap rejection
  // before the terrain height under the obstacle is computed).
  const double dxy2 = d.x() * d.x() + d.y() * d.y();
  // With many obstacles: the x-y box of the part of the ray that can meet one (set below), a
  // cheaper first rejection.
  bool use_box = false;
  double box_lo[2] = {0.0, 0.0}, box_hi[2] = {0.0, 0.0};
  auto nearTrace = [&](const Eigen::Vector2d& c, double radius) {
    if (use_box && (c.x() + radius < box_lo[0] || c.x() - radius > box_hi[0] ||
                    c.y() + radius < box_lo[1] || c.y() - radius > box_hi[1])) {
      return false;
    }
    const double cx = c.x() - o.x(), cy = c.y() - o.y();
    double t = dxy2 > 0.0 ? (cx * d.x() + cy * d.y()) / dxy2 : 0.0;
    t = std::clamp(t, 0.0, t_best);
    const double ex = cx - t * d.x(), ey = cy - t * d.y();
    return ex * ex + ey * ey <= radius * radius;
  };
  auto testBox = [&](size_t i) {
    const BoxObstacle& bx = so.boxes[i];
    const BoxCache& bc = box_cache_[i];
    const Eigen::Vector2d c = bc.moving ? bx.centerAt(time_s) : bx.center_xy;
    if (!nearTrace(c, bc.radius)) return;
    const double zb = bc.moving ? terrain_->height(c.x(), c.y()) : bc.terrain_z;
    const double cy = bc.cos_yaw, sy = bc.sin_yaw;
    const Eigen::Vector3d lo(cy * (o.x() - c.x()) + sy * (o.y() - c.y()),
                             -sy * (o.x() - c.x()) + cy * (o.y() - c.y()), o.z() - zb);
    const Eigen::Vector3d ld(cy * d.x() + sy * d.y(), -sy * d.x() + cy * d.y(), d.z());
    const double lo_b[3] = {-0.5 * bx.length_m, -0.5 * bx.width_m, -kObstacleBuryM};
    const double hi_b[3] = {0.5 * bx.length_m, 0.5 * bx.width_m, bx.height_m};
    double t_near = -kInf, t_far = kInf;
    int near_axis = -1;
    bool near_positive = false;
    bool miss = false;
    for (int a = 0; a < 3 && !miss; ++a) {
      if (ld[a] == 0.0) {
        if (lo[a] < lo_b[a] || lo[a] > hi_b[a]) miss = true;
        continue;
      }
      double t0 = (lo_b[a] - lo[a]) / ld[a];
      double t1 = (hi_b[a] - lo[a]) / ld[a];
      bool pos = false;  // entering through the positive face?
      if (t0 > t1) {
        std::swap(t0, t1);
        pos = true;
      }
      if (t0 > t_near) {
        t_near = t0;
        near_axis = a;
        near_positive = pos;
      }
      t_far = std::min(t_far, t1);
      if (t_near > t_far) miss = true;
    }
    if (miss || near_axis < 0 || !(t_near > 0.0) || !(t_near < t_best)) return;
    t_best = t_near;
    best.t = t_near;
    best.point = o + t_near * d;
    best.object_id = static_cast<int>(i) + 1;
    best.surface = kBoxFaceBase + near_axis * 2 + (near_positive ? 1 : 0);
    Eigen::Vector3d n_local = Eigen::Vector3d::Zero();
    n_local[near_axis] = near_positive ? 1.0 : -1.0;
    best.normal = Eigen::Vector3d(cy * n_local.x() - sy * n_local.y(),
                                  sy * n_local.x() + cy * n_local.y(), n_local.z());
  };
  auto testPole = [&](size_t j) {
    const PoleObstacle& pl = so.poles[j];
    if (!nearTrace(pl.xy, pl.radius_m + 1e-9)) return;
    const double zb = pole_terrain_z_[j];
    const double z0 = zb - kObstacleBuryM, z1 = zb + pl.height_m;
    const double px = o.x() - pl.xy.x(), py = o.y() - pl.xy.y();
    const double r2 = pl.radius_m * pl.radius_m;
    const int id = static_cast<int>(so.boxes.size() + j) + 1;
    if (px * px + py * py <= r2) return;  // origin inside the pole's footprint: ignore
    const double qa = d.x() * d.x() + d.y() * d.y();
    if (qa > 0.0) {
      const double qb = px * d.x() + py * d.y();
      const double qc = px * px + py * py - r2;
      const double disc = qb * qb - qa * qc;
      if (disc >= 0.0) {
        const double t = (-qb - std::sqrt(disc)) / qa;
        const double z = o.z() + t * d.z();
        if (t > 0.0 && t < t_best && z >= z0 && z <= z1) {
          t_best = t;
          best.t = t;
          best.point = o + t * d;
          best.object_id = id;
          best.surface = kPoleSide;
          best.normal = Eigen::Vector3d(px + t * d.x(), py + t * d.y(), 0.0).normalized();
        }
      }
    }
    if (d.z() < 0.0 && o.z() > z1) {
      const double t = (z1 - o.z()) / d.z();
      const double hx = px + t * d.x(), hy = py + t * d.y();
      if (t > 0.0 && t < t_best && hx * hx + hy * hy <= r2) {
        t_best = t;
        best.t = t;
        best.point = o + t * d;
        best.object_id = id;
        best.surface = kPoleTop;
        best.normal = Eigen::Vector3d::UnitZ();
      }
    }
  };
  if (grid_.empty()) {
    for (size_t i = 0; i < so.boxes.size(); ++i) testBox(i);
    for (size_t j = 0; j < so.poles.size(); ++j) testPole(j);
    return best;
  }
  // Many obstacles: the moving boxes and the static obstacles near the ray's trace inside the
  // slab that holds every obstacle.
  double ta = 0.0, tb = t_max;
  if (d.z() == 0.0) {
    if (o.z() < obstacle_z_lo_ || o.z() > obstacle_z_hi_) tb = -1.0;
  } else {
    double u0 = (obstacle_z_lo_ - o.z()) / d.z(), u1 = (obstacle_z_hi_ - o.z()) / d.z();
    if (u0 > u1) std::swap(u0, u1);
    ta = std::max(ta, u0);
    tb = std::min(tb, u1);
  }
  if (!(ta <= tb)) return best;
  use_box = std::isfinite(tb);
  for (int a = 0; a < 2; ++a) {
    const double p0 = o[a] + ta * d[a], p1 = o[a] + tb * d[a];
    box_lo[a] = std::min(p0, p1) - 1e-9 * (1.0 + std::abs(p0) + std::abs(p1));
    box_hi[a] = std::max(p0, p1) + 1e-9 * (1.0 + std::abs(p0) + std::abs(p1));
  }
  for (int i : moving_boxes_) testBox(static_cast<size_t>(i));
  // Static obstacles cell by cell, nearest first, each tested once (stamps); done when the best
  // hit so far lies before the next cell.
  thread_local std::vector<uint32_t> stamps;
  thread_local uint32_t stamp = 0;
  if (stamps.size() < static_cast<size_t>(obstacleCount())) stamps.assign(obstacleCount(), 0);
  if (++stamp == 0) {
    std::fill(stamps.begin(), stamps.end(), 0);
    stamp = 1;
  }
  const auto nb = static_cast<int>(so.boxes.size());
  grid_.walk(o, d, ta, std::min(tb, t_best), [&](const int* ids, int n, double t_exit) {
    for (int k = 0; k < n; ++k) {
      const int id = ids[k];
      if (stamps[static_cast<size_t>(id)] == stamp) continue;
      stamps[static_cast<size_t>(id)] = stamp;
      if (id < nb) {
        testBox(static_cast<size_t>(id));
      } else {
        testPole(static_cast<size_t>(id - nb));
      }
    }
    return !(t_best <= t_exit);
  });
  return best;
}

}  // namespace stereo_ground_dem::sim
