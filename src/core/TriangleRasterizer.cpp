#include "stereo_ground_dem/TriangleRasterizer.hpp"

#include <algorithm>
#include <cmath>

namespace stereo_ground_dem {

void TriangleRasterizer::reset(int width, int height, int margin) {
  if (labels_.rows != height || labels_.cols != width || row_begin_.size() != static_cast<size_t>(height)) {
    labels_.create(height, width, CV_32S);
    inv_depth_.create(height, width, CV_32F);
    labels_.setTo(-1);
    inv_depth_.setTo(0.0f);
  } else {
    // only what the last drawing touched: each row's [first, last] labelled column
    for (int v = 0; v < height; ++v) {
      const int b = row_begin_[static_cast<size_t>(v)], e = row_end_[static_cast<size_t>(v)];
      if (b > e) continue;
      std::fill(labels_.ptr<int>(v) + b, labels_.ptr<int>(v) + e + 1, -1);
      std::fill(inv_depth_.ptr<float>(v) + b, inv_depth_.ptr<float>(v) + e + 1, 0.0f);
    }
  }
  row_begin_.assign(static_cast<size_t>(height), width);
  row_end_.assign(static_cast<size_t>(height), -1);
  margin_ = margin;
}

int TriangleRasterizer::draw(const Triangle& t, int first_row, int last_row) {
  const double area2 = (t.u[1] - t.u[0]) * (t.v[2] - t.v[0]) - (t.v[1] - t.v[0]) * (t.u[2] - t.u[0]);
  if (!(std::abs(area2) > 1e-12)) return 0;
  const double sgn = area2 > 0 ? 1.0 : -1.0;
  const int w = labels_.cols, h = labels_.rows;
  const double vmin = std::min({t.v[0], t.v[1], t.v[2]});
  const double vmax = std::max({t.v[0], t.v[1], t.v[2]});
  const double umin = std::min({t.u[0], t.u[1], t.u[2]});
  const double umax = std::max({t.u[0], t.u[1], t.u[2]});
  const int r0 = std::max({margin_, first_row, static_cast<int>(std::ceil(vmin))});
  const int r1 = std::min({h - 1 - margin_, last_row, static_cast<int>(std::floor(vmax))});
  const int cmin = std::max(margin_, static_cast<int>(std::ceil(umin)));
  const int cmax = std::min(w - 1 - margin_, static_cast<int>(std::floor(umax)));
  if (r0 > r1 || cmin > cmax) return 0;
  // Edge i: E_i(u, v) = sgn * ((u_{i+1} - u_i)(v - v_i) - (v_{i+1} - v_i)(u - u_i)) >= 0 inside,
  // i.e. A_i u + B_i(v) >= 0 with A_i = -sgn * (v_{i+1} - v_i).
  double ea[3], eb[3], ec[3], inv_ea[3];
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    const double du = t.u[j] - t.u[i], dv = t.v[j] - t.v[i];
    ea[i] = -sgn * dv;
    eb[i] = sgn * du;
    ec[i] = sgn * (-du * t.v[i] + dv * t.u[i]);
    inv_ea[i] = ea[i] != 0.0 ? 1.0 / ea[i] : 0.0;
  }
  constexpr double kEps = 1e-9;
  int won = 0;
  for (int v = r0; v <= r1; ++v) {
    double lo = cmin, hi = cmax;
    bool empty = false;
    for (int i = 0; i < 3; ++i) {
      const double k = eb[i] * v + ec[i];  // ea u + k >= 0
      if (ea[i] > kEps) {
        lo = std::max(lo, -k * inv_ea[i]);
      } else if (ea[i] < -kEps) {
        hi = std::min(hi, -k * inv_ea[i]);
      } else if (k < -kEps) {
        empty = true;
      }
    }
    if (empty) continue;
    const int c0 = static_cast<int>(std::ceil(lo - 1e-9));
    const int c1 = static_cast<int>(std::floor(hi + 1e-9));
    if (c0 > c1) continue;
    int* lab = labels_.ptr<int>(v);
    float* rho = inv_depth_.ptr<float>(v);
    const float ra = static_cast<float>(t.rho_a), base = static_cast<float>(t.rho_b * v + t.rho_c);
    const int id = t.id;
    int won_row = 0;
    for (int c = c0; c <= c1; ++c) {  // branch-free: the nearer surface wins the pixel
      const float r = ra * static_cast<float>(c) + base, old = rho[c];
      const int nearer = r > old ? -1 : 0;  // all bits set where this triangle wins
      rho[c] = r > old ? r : old;
      lab[c] = (id & nearer) | (lab[c] & ~nearer);
      won_row -= nearer;
    }
    if (won_row > 0) {
      won += won_row;
      auto& b = row_begin_[static_cast<size_t>(v)];
      auto& e = row_end_[static_cast<size_t>(v)];
      b = std::min(b, c0);
      e = std::max(e, c1);
    }
  }
  return won;
}

}  // namespace stereo_ground_dem
