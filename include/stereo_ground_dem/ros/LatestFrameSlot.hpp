#pragma once
/// \file LatestFrameSlot.hpp
/// A one-element hand-off between the image callback and the processing thread: put() stores the
/// newest item, replacing one that was not taken yet (the replaced item is returned so the caller
/// can count it as dropped: never queued); take() blocks until an item, a wake-up or close().
///
/// Why one element: the estimator needs 0.1-0.3 s per full-resolution frame, a camera delivers a
/// frame every 0.1 s. A queue would grow the latency by one processing time per queued frame; the
/// slot keeps it below two processing times and always processes the newest image.
/// No ROS dependency (tested in test/ros/test_ros_conversions.cpp).

#include <condition_variable>
#include <mutex>
#include <optional>
#include <utility>

namespace stereo_ground_dem {

template <class T>
class LatestFrameSlot {
 public:
  enum class Taken { kItem, kWoken, kClosed };

  /// Stores `item`; returns the unprocessed item it replaced, if any. After close() the item is
  /// returned as it is (nobody will take it).
  std::optional<T> put(T item) {
    std::optional<T> replaced;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_) return std::optional<T>(std::move(item));
      ++puts_;
      if (item_ && hold_) return std::optional<T>(std::move(item));  // the held one stays
      if (item_) replaced = std::move(item_);
      item_ = std::move(item);
    }
    cv_.notify_one();
    return replaced;
  }

  /// Blocks until an item is there (moved into *out: kItem), wake() was called (kWoken; an item
  /// present at the same time is taken first), or close() (kClosed; a pending item is discarded).
  Taken take(T* out) {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return closed_ || item_.has_value() || woken_; });
    if (closed_) return Taken::kClosed;
    if (item_) {
      *out = std::move(*item_);
      item_.reset();
      hold_ = false;
      return Taken::kItem;
    }
    woken_ = false;
    return Taken::kWoken;
  }

  /// Until the next item is taken, the first item put is kept and later ones are dropped (put()
  /// returns them) instead of replacing it: the frame right after one that initializes the
  /// estimator must be the next one, not the newest (the motion search without a velocity finds
  /// steps of up to ~4 m, not the 6 m of the 0.5 s an initialization takes at 44 km/h).
  void holdNext() {
    std::lock_guard<std::mutex> lock(mutex_);
    hold_ = true;
  }
  /// Makes one take() return kWoken (sticky until then): the consumer has other work (a reset).
  void wake() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      woken_ = true;
    }
    cv_.notify_one();
  }

  /// Ends every take() (now and later) with kClosed.
  void close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
      item_.reset();
    }
    cv_.notify_all();
  }

  bool occupied() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return item_.has_value();
  }
  /// Items put since construction.
  long puts() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return puts_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::optional<T> item_;
  bool woken_ = false;
  bool hold_ = false;
  bool closed_ = false;
  long puts_ = 0;
};

}  // namespace stereo_ground_dem
