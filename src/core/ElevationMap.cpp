#include "stereo_ground_dem/ElevationMap.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <dirent.h>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {
int floorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr char kMagic[8] = {'S', 'G', 'D', 'T', 'I', 'L', 'E', '2'};
constexpr std::int32_t kTileHasRefuted = 1;  ///< header flag: one byte per vertex of refuted marks at the end
}  // namespace

bool ElevationMapOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(resolution_m > 0.0)) return bad("resolution_m must be > 0");
  if (tile_size < 8 || tile_size > 1024) return bad("tile_size must be in 8..1024");
  if (!(keep_radius_m > 0.0)) return bad("keep_radius_m must be > 0");
  if (!(max_information > 0.0)) return bad("max_information must be > 0");
  if (!(obstacle_hit > 0.0) || !(obstacle_miss > 0.0) || !(obstacle_mark_score > 0.0) ||
      !(obstacle_max_score >= obstacle_mark_score)) {
    return bad("obstacle scores: need hit, miss and mark > 0 and max_score >= mark_score");
  }
  return true;
}

ElevationMap::ElevationMap(const ElevationMapOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("ElevationMapOptions: " + why);
}

ElevationMap::Tile* ElevationMap::tileFor(int lr, int lc, bool create, int* index) {
  const int ts = options_.tile_size;
  const int tr = floorDiv(lr, ts), tc = floorDiv(lc, ts);
  *index = (lr - tr * ts) * ts + (lc - tc * ts);
  const Key k = key(tr, tc);
  auto it = tiles_.find(k);
  if (it != tiles_.end()) return &it->second;
  if (!create) return nullptr;
  Tile t;
  const size_t n = static_cast<size_t>(ts) * static_cast<size_t>(ts);
  t.height.assign(n, kNaN);
  t.information.assign(n, 0.0f);
  t.observations.assign(n, 0);
  t.last_update.assign(n, -1);
  t.obstacle_score.assign(n, 0.0f);
  t.obstacle_height.assign(n, kNaN);
  t.refuted.assign(n, 0);
  return &tiles_.emplace(k, std::move(t)).first->second;
}

const ElevationMap::Tile* ElevationMap::tileFor(int lr, int lc, int* index) const {
  return const_cast<ElevationMap*>(this)->tileFor(lr, lc, false, index);
}

void ElevationMap::sample(const GroundGrid& w, Eigen::VectorXd* heights, Eigen::VectorXd* information,
                          Eigen::VectorXi* observations) const {
  if (std::abs(w.resolution_m - options_.resolution_m) > 1e-9) {
    throw std::invalid_argument("ElevationMap::sample: window resolution differs from the map's");
  }
  heights->setConstant(w.vertexCount(), std::numeric_limits<double>::quiet_NaN());
  information->setZero(w.vertexCount());
  if (observations) observations->setZero(w.vertexCount());
  for (int r = 0; r < w.rows; ++r) {
    for (int c = 0; c < w.cols; ++c) {
      int i = 0;
      const Tile* t = tileFor(w.row0 + r, w.col0 + c, &i);
      if (!t) continue;
      const size_t si = static_cast<size_t>(i);
      const int v = w.index(r, c);
      (*heights)[v] = t->height[si];
      (*information)[v] = t->information[si];
      if (observations) (*observations)[v] = t->observations[si];
    }
  }
}

void ElevationMap::fuse(const GroundGrid& w, const Eigen::VectorXd& heights, const Eigen::VectorXd& prior_information,
                        const Eigen::VectorXd& data_information, const std::vector<uint8_t>& update,
                        int frame_index) {
  if (std::abs(w.resolution_m - options_.resolution_m) > 1e-9) {
    throw std::invalid_argument("ElevationMap::fuse: window resolution differs from the map's");
  }
  for (int r = 0; r < w.rows; ++r) {
    for (int c = 0; c < w.cols; ++c) {
      const int v = w.index(r, c);
      if (!update[static_cast<size_t>(v)] || !std::isfinite(heights[v])) continue;
      int i = 0;
      Tile* t = tileFor(w.row0 + r, w.col0 + c, true, &i);
      const size_t si = static_cast<size_t>(i);
      const double info = std::min(options_.max_information,
                                   std::max(0.0, prior_information[v]) + std::max(0.0, data_information[v]));
      t->height[si] = static_cast<float>(heights[v]);
      t->information[si] = static_cast<float>(info);
      if (t->observations[si] < 65535) t->observations[si]++;
      t->last_update[si] = frame_index;
      t->refuted[si] = 0;
    }
  }
}

int ElevationMap::markRefuted(const GroundGrid& w, const Eigen::VectorXd& ceilings, double margin_m,
                              const std::vector<uint8_t>& update) {
  if (ceilings.size() != w.vertexCount() || update.size() != static_cast<size_t>(w.vertexCount())) {
    throw std::invalid_argument("ElevationMap::markRefuted: ceilings or update do not match the window");
  }
  int marked = 0;
  for (int r = 0; r < w.rows; ++r) {
    for (int c = 0; c < w.cols; ++c) {
      const int v = w.index(r, c);
      if (update[static_cast<size_t>(v)] || !std::isfinite(ceilings[v])) continue;
      int i = 0;
      Tile* t = tileFor(w.row0 + r, w.col0 + c, false, &i);
      if (!t) continue;
      const size_t si = static_cast<size_t>(i);
      if (t->refuted[si] || !(t->information[si] > 0.0f) || !(t->height[si] > ceilings[v] + margin_m)) continue;
      t->refuted[si] = 1;
      ++marked;
    }
  }
  return marked;
}

void ElevationMap::updateObstacles(const GroundGrid& w, const std::vector<uint8_t>& hit,
                                   const std::vector<uint8_t>& ground, const Eigen::VectorXd& height, int frame_index) {
  for (int r = 0; r < w.rows; ++r) {
    for (int c = 0; c < w.cols; ++c) {
      const size_t v = static_cast<size_t>(w.index(r, c));
      if (!hit[v] && !ground[v]) continue;
      int i = 0;
      Tile* t = tileFor(w.row0 + r, w.col0 + c, hit[v] != 0, &i);
      if (!t) continue;
      const size_t si = static_cast<size_t>(i);
      float& s = t->obstacle_score[si];
      if (hit[v]) {
        s = static_cast<float>(std::min(options_.obstacle_max_score, s + options_.obstacle_hit));
        if (std::isfinite(height[static_cast<Eigen::Index>(v)])) t->obstacle_height[si] = static_cast<float>(height[static_cast<Eigen::Index>(v)]);
        t->last_update[si] = std::max(t->last_update[si], frame_index);
      } else {
        s = static_cast<float>(std::max(-options_.obstacle_max_score, s - options_.obstacle_miss));
        if (s < options_.obstacle_mark_score) t->obstacle_height[si] = kNaN;
      }
    }
  }
}

void ElevationMap::writeTile(const std::string& directory, Key k, const Tile& t) const {
  const int tr = static_cast<int>(k >> 32);
  const int tc = static_cast<int>(static_cast<std::int32_t>(k & 0xffffffff));
  const std::string path = directory + "/tile_" + std::to_string(tr) + "_" + std::to_string(tc) + ".bin";
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("ElevationMap: cannot write archive tile '" + path + "'");
  // header[3]: flags; bit 0 = the refuted marks follow the obstacle heights (older tiles: 0)
  const std::int32_t header[4] = {tr, tc, options_.tile_size, kTileHasRefuted};
  const double res = options_.resolution_m;
  out.write(kMagic, sizeof(kMagic));
  out.write(reinterpret_cast<const char*>(header), sizeof(header));
  out.write(reinterpret_cast<const char*>(&res), sizeof(res));
  const auto n = static_cast<std::streamsize>(t.height.size());
  out.write(reinterpret_cast<const char*>(t.height.data()), n * 4);
  out.write(reinterpret_cast<const char*>(t.information.data()), n * 4);
  out.write(reinterpret_cast<const char*>(t.observations.data()), n * 2);
  out.write(reinterpret_cast<const char*>(t.last_update.data()), n * 4);
  out.write(reinterpret_cast<const char*>(t.obstacle_score.data()), n * 4);
  out.write(reinterpret_cast<const char*>(t.obstacle_height.data()), n * 4);
  out.write(reinterpret_cast<const char*>(t.refuted.data()), n);
  out.close();
  if (!out) throw std::runtime_error("ElevationMap: cannot write archive tile '" + path + "' (disk full?)");
}

void ElevationMap::archive(Key k, const Tile& t) const {
  if (options_.archive_directory.empty()) return;
  writeTile(options_.archive_directory, k, t);
}

int ElevationMap::saveTiles(const std::string& directory) const {
  for (const auto& kv : tiles_) writeTile(directory, kv.first, kv.second);
  return static_cast<int>(tiles_.size());
}

int ElevationMap::loadArchive(const std::string& directory) {
  DIR* d = opendir(directory.c_str());
  if (!d) throw std::runtime_error("ElevationMap: cannot open archive directory '" + directory + "'");
  int loaded = 0;
  while (dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name.rfind("tile_", 0) != 0 || name.size() < 9 || name.substr(name.size() - 4) != ".bin") continue;
    std::ifstream in(directory + "/" + name, std::ios::binary);
    char magic[8];
    std::int32_t header[4];
    double res = 0.0;
    in.read(magic, 8);
    in.read(reinterpret_cast<char*>(header), sizeof(header));
    in.read(reinterpret_cast<char*>(&res), sizeof(res));
    if (!in || !std::equal(magic, magic + 8, kMagic) || header[2] != options_.tile_size ||
        std::abs(res - options_.resolution_m) > 1e-9) {
      closedir(d);
      throw std::runtime_error("ElevationMap: '" + name + "' is not a tile of this map's layout");
    }
    Tile t;
    const size_t n = static_cast<size_t>(options_.tile_size) * static_cast<size_t>(options_.tile_size);
    t.height.resize(n);
    t.information.resize(n);
    t.observations.resize(n);
    t.last_update.resize(n);
    t.obstacle_score.resize(n);
    t.obstacle_height.resize(n);
    t.refuted.assign(n, 0);  // tiles written before the marks existed: none
    in.read(reinterpret_cast<char*>(t.height.data()), static_cast<std::streamsize>(n * 4));
    in.read(reinterpret_cast<char*>(t.information.data()), static_cast<std::streamsize>(n * 4));
    in.read(reinterpret_cast<char*>(t.observations.data()), static_cast<std::streamsize>(n * 2));
    in.read(reinterpret_cast<char*>(t.last_update.data()), static_cast<std::streamsize>(n * 4));
    in.read(reinterpret_cast<char*>(t.obstacle_score.data()), static_cast<std::streamsize>(n * 4));
    in.read(reinterpret_cast<char*>(t.obstacle_height.data()), static_cast<std::streamsize>(n * 4));
    if (header[3] & kTileHasRefuted) in.read(reinterpret_cast<char*>(t.refuted.data()), static_cast<std::streamsize>(n));
    if (!in) {
      closedir(d);
      throw std::runtime_error("ElevationMap: archive tile '" + name + "' is truncated");
    }
    tiles_[key(header[0], header[1])] = std::move(t);
    ++loaded;
  }
  closedir(d);
  return loaded;
}

int ElevationMap::evictFarFrom(double x, double y) {
  const double tile_m = options_.tile_size * options_.resolution_m;
  int n = 0;
  for (auto it = tiles_.begin(); it != tiles_.end();) {
    const int tr = static_cast<int>(it->first >> 32);
    const int tc = static_cast<int>(static_cast<std::int32_t>(it->first & 0xffffffff));
    const double cx = (tc + 0.5) * tile_m, cy = (tr + 0.5) * tile_m;
    if (std::hypot(cx - x, cy - y) > options_.keep_radius_m) {
      archive(it->first, it->second);
      it = tiles_.erase(it);
      ++n;
    } else {
      ++it;
    }
  }
  evicted_ += n;
  return n;
}

GroundGrid ElevationMap::bounds() const {
  GroundGrid g;
  g.resolution_m = options_.resolution_m;
  if (tiles_.empty()) return g;
  int rmin = std::numeric_limits<int>::max(), cmin = rmin, rmax = std::numeric_limits<int>::min(), cmax = rmax;
  for (const auto& kv : tiles_) {
    const int tr = static_cast<int>(kv.first >> 32);
    const int tc = static_cast<int>(static_cast<std::int32_t>(kv.first & 0xffffffff));
    rmin = std::min(rmin, tr);
    rmax = std::max(rmax, tr);
    cmin = std::min(cmin, tc);
    cmax = std::max(cmax, tc);
  }
  const int ts = options_.tile_size;
  g.row0 = rmin * ts;
  g.col0 = cmin * ts;
  g.rows = (rmax - rmin + 1) * ts;
  g.cols = (cmax - cmin + 1) * ts;
  return g;
}

GroundGrid ElevationMap::knownBounds() const {
  GroundGrid g;
  g.resolution_m = options_.resolution_m;
  int rmin = std::numeric_limits<int>::max(), cmin = rmin, rmax = std::numeric_limits<int>::min(), cmax = rmax;
  const int ts = options_.tile_size;
  for (const auto& kv : tiles_) {
    const int tr = static_cast<int>(kv.first >> 32);
    const int tc = static_cast<int>(static_cast<std::int32_t>(kv.first & 0xffffffff));
    for (int i = 0; i < ts * ts; ++i) {
      if (!std::isfinite(kv.second.height[static_cast<size_t>(i)]) &&
          kv.second.obstacle_score[static_cast<size_t>(i)] < options_.obstacle_mark_score) {
        continue;
      }
      const int r = tr * ts + i / ts, c = tc * ts + i % ts;
      rmin = std::min(rmin, r);
      rmax = std::max(rmax, r);
      cmin = std::min(cmin, c);
      cmax = std::max(cmax, c);
    }
  }
  if (rmax < rmin) return g;
  g.row0 = rmin;
  g.col0 = cmin;
  g.rows = rmax - rmin + 1;
  g.cols = cmax - cmin + 1;
  return g;
}

cv::Mat ElevationMap::layer(Layer which, const GroundGrid& w) const {
  cv::Mat out(w.rows, w.cols, CV_32F, cv::Scalar(kNaN));
  for (int r = 0; r < w.rows; ++r) {
    float* row = out.ptr<float>(r);
    for (int c = 0; c < w.cols; ++c) {
      int i = 0;
      const Tile* t = tileFor(w.row0 + r, w.col0 + c, &i);
      if (!t) continue;
      const size_t si = static_cast<size_t>(i);
      const bool obstacle = t->obstacle_score[si] >= options_.obstacle_mark_score;
      // A height fused without information (the frame's last linearization did not see the
      // vertex, and the map knew nothing there) is no measurement: the estimator starts such a
      // vertex as unknown, and the layers publish it as unknown (a height always has a variance).
      // A height a far ray refuted (markRefuted) is published as unknown until it is fused again.
      const bool known = std::isfinite(t->height[si]) && t->information[si] > 0.0f && !t->refuted[si];
      if (which == Layer::kObstacle) {
        if (obstacle) row[c] = 1.0f;
        else if (known) row[c] = 0.0f;
        continue;
      }
      if (which == Layer::kObstacleHeight) {
        if (obstacle) row[c] = t->obstacle_height[si];
        continue;
      }
      if (!known) continue;
      switch (which) {
        case Layer::kElevation: row[c] = t->height[si]; break;
        case Layer::kVariance: row[c] = 1.0f / t->information[si]; break;
        case Layer::kObservations: row[c] = t->observations[si]; break;
        case Layer::kLastUpdate: row[c] = static_cast<float>(t->last_update[si]); break;
        default: break;
      }
    }
  }
  return out;
}

void ElevationMap::clear() {
  tiles_.clear();
  evicted_ = 0;
}

size_t ElevationMap::memoryBytes() const {
  const size_t n = static_cast<size_t>(options_.tile_size) * static_cast<size_t>(options_.tile_size);
  return tiles_.size() * (n * (4 + 4 + 2 + 4 + 4 + 4 + 1) + sizeof(Tile) + 32);
}

}  // namespace stereo_ground_dem
