#pragma once
/// \file LatticeTiles.hpp
/// Square tiles of per-node data over an unbounded ground lattice (node (i, j) at (x, y) = (j, i) *
/// resolution_m, GroundGrid's conventions), created on first write and evicted by distance, for the
/// map layers that live beside the ElevationMap (OrthoTexture, PhotometricResidualMap).
///
/// Copies share their tiles (copy on write): find(create) clones a tile another copy still holds
/// before handing it out for writing, so a copy made after every frame for readers on other threads
/// costs only the tiles the next frame touches. use_count() can only drop meanwhile (copies are made
/// on the writer's thread), which at worst clones once too often.
///
/// `Tile` needs a constructor Tile(size_t nodes) that fills it with "unknown", and for write() /
/// read() a `template <class Self, class F> static void forEachBuffer(Self& tile, F f)` that calls
/// f(std::vector<T>&) on each of its per-node arrays.

#include <atomic>
#include <climits>
#include <cmath>
#include <cstdint>
#include <memory>
#include <istream>
#include <ostream>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace stereo_ground_dem {

template <class Tile>
class LatticeTiles {
 public:
  LatticeTiles(int tile_size, double resolution_m) : tile_size_(tile_size), resolution_m_(resolution_m) {}

  /// The tile holding node (i, j) and the node's index in it; nullptr if absent and !create.
  Tile* find(long long i, long long j, size_t* index, bool create) {
    long long tr = 0, tc = 0;
    locate(i, j, &tr, &tc, index);
    auto it = tiles_.find(key(tr, tc));
    if (it != tiles_.end()) {
      if (it->second.use_count() > 1) {
        it->second = std::make_shared<Tile>(*it->second);
      } else {
        // the last other holder may have just let go on another thread: its reads happen before
        // our writes (shared_ptr's release decrement pairs with this acquire)
        std::atomic_thread_fence(std::memory_order_acquire);
      }
      return it->second.get();
    }
    if (!create) return nullptr;
    const size_t n = static_cast<size_t>(tile_size_) * static_cast<size_t>(tile_size_);
    return tiles_.emplace(key(tr, tc), std::make_shared<Tile>(n)).first->second.get();
  }
  const Tile* find(long long i, long long j, size_t* index) const {
    long long tr = 0, tc = 0;
    locate(i, j, &tr, &tc, index);
    const auto it = tiles_.find(key(tr, tc));
    return it == tiles_.end() ? nullptr : it->second.get();
  }

  /// Reads many nearby nodes: remembers the last tile, so that a hash lookup is made only when the
  /// tile changes.
  class Reader {
   public:
    explicit Reader(const LatticeTiles& tiles) : tiles_(tiles) {}
    const Tile* find(long long i, long long j, size_t* index) {
      long long tr = 0, tc = 0;
      tiles_.locate(i, j, &tr, &tc, index);
      if (tr != tr_ || tc != tc_) {
        tr_ = tr;
        tc_ = tc;
        const auto it = tiles_.tiles_.find(key(tr, tc));
        tile_ = it == tiles_.tiles_.end() ? nullptr : it->second.get();
      }
      return tile_;
    }

   private:
    const LatticeTiles& tiles_;
    long long tr_ = LLONG_MIN, tc_ = LLONG_MIN;
    const Tile* tile_ = nullptr;
  };

  /// Calls f(first node row, first node column, tile) for every tile.
  template <class F>
  void forEach(F f) const {
    for (const auto& [k, tile] : tiles_) {
      const long long tr = static_cast<std::int32_t>(static_cast<std::uint64_t>(k) >> 32);
      const long long tc = static_cast<std::int32_t>(static_cast<std::uint64_t>(k) & 0xffffffffu);
      f(tr * tile_size_, tc * tile_size_, *tile);
    }
  }

  /// Removes the tiles whose centre is farther than radius_m from (x, y); returns how many.
  int evictFarFrom(double x, double y, double radius_m) {
    const double side = tile_size_ * resolution_m_;
    int removed = 0;
    for (auto it = tiles_.begin(); it != tiles_.end();) {
      const long long tr = static_cast<std::int32_t>(static_cast<std::uint64_t>(it->first) >> 32);
      const long long tc = static_cast<std::int32_t>(static_cast<std::uint64_t>(it->first) & 0xffffffffu);
      if (std::hypot((tc + 0.5) * side - x, (tr + 0.5) * side - y) > radius_m) {
        it = tiles_.erase(it);
        ++removed;
      } else {
        ++it;
      }
    }
    return removed;
  }

  void clear() { tiles_.clear(); }
  size_t size() const { return tiles_.size(); }

  /// Every tile to `out` (binary, host byte order): a header (magic, tile size, resolution, tile
  /// count), then per tile its key and the arrays forEachBuffer lists.
  void write(std::ostream& out) const {
    const std::int64_t header[2] = {tile_size_, static_cast<std::int64_t>(tiles_.size())};
    out.write(kMagic, sizeof(kMagic));
    out.write(reinterpret_cast<const char*>(header), sizeof(header));
    out.write(reinterpret_cast<const char*>(&resolution_m_), sizeof(resolution_m_));
    for (const auto& [k, tile] : tiles_) {
      out.write(reinterpret_cast<const char*>(&k), sizeof(k));
      Tile::forEachBuffer(static_cast<const Tile&>(*tile), [&](const auto& v) {
        out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(v[0])));
      });
    }
  }
  /// Replaces the tiles with what write() wrote; throws std::runtime_error (and keeps the tiles)
  /// when the stream is not such a record, has another tile size or resolution, or is truncated.
  void read(std::istream& in) {
    char magic[sizeof(kMagic)] = {};
    std::int64_t header[2] = {0, 0};
    double resolution = 0.0;
    in.read(magic, sizeof(magic));
    in.read(reinterpret_cast<char*>(header), sizeof(header));
    in.read(reinterpret_cast<char*>(&resolution), sizeof(resolution));
    if (!in || std::string(magic, sizeof(magic)) != std::string(kMagic, sizeof(kMagic)))
      throw std::runtime_error("not a tile record of this program");
    if (header[0] != tile_size_ || std::abs(resolution - resolution_m_) > 1e-9)
      throw std::runtime_error("tiles of " + std::to_string(header[0]) + " nodes at " + std::to_string(resolution) +
                               " m, this map has " + std::to_string(tile_size_) + " at " +
                               std::to_string(resolution_m_) + " m");
    if (header[1] < 0 || header[1] > (1LL << 24)) throw std::runtime_error("implausible tile count");
    const size_t n = static_cast<size_t>(tile_size_) * static_cast<size_t>(tile_size_);
    std::unordered_map<Key, std::shared_ptr<Tile>> tiles;
    for (std::int64_t t = 0; t < header[1]; ++t) {
      Key k = 0;
      in.read(reinterpret_cast<char*>(&k), sizeof(k));
      auto tile = std::make_shared<Tile>(n);
      Tile::forEachBuffer(*tile, [&](auto& v) {
        in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(v[0])));
      });
      if (!in) throw std::runtime_error("the tile record is truncated");
      tiles[k] = std::move(tile);
    }
    tiles_ = std::move(tiles);
  }
  int tileSize() const { return tile_size_; }

 private:
  using Key = std::int64_t;
  static constexpr char kMagic[8] = {'S', 'G', 'D', 'L', 'T', 'I', 'L', '1'};
  static Key key(long long tile_row, long long tile_col) {
    return static_cast<Key>((static_cast<std::uint64_t>(static_cast<std::uint32_t>(tile_row)) << 32) |
                            static_cast<std::uint32_t>(tile_col));
  }
  static long long floorDiv(long long a, long long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
  void locate(long long i, long long j, long long* tr, long long* tc, size_t* index) const {
    const long long ts = tile_size_;
    *tr = floorDiv(i, ts);
    *tc = floorDiv(j, ts);
    *index = static_cast<size_t>((i - *tr * ts) * ts + (j - *tc * ts));
  }

  int tile_size_;
  double resolution_m_;
  std::unordered_map<Key, std::shared_ptr<Tile>> tiles_;
};

}  // namespace stereo_ground_dem
