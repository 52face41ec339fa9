// Bounded, time-ordered hand-over queue between DDS listener threads (producers) and the core's
// executor thread (consumer). Push never blocks: a listener thread must not wait for the core.
// When full, the OLDEST item is evicted and returned to the caller, which counts/logs it.
//
// Ordering is local: an item up to `reorder_window_s` older than queued ones is sorted in (two
// DDS readers, transport reordering); an item older by more than that is a time jump (a bag
// replay looping, a clock reset) and is appended, so the consumer sees one clean jump back instead
// of two timelines interleaved.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

namespace ppf::dds {

template <typename T>
class TimeOrderedQueue {
 public:
  explicit TimeOrderedQueue(size_t capacity, double reorder_window_s = 0.5)
      : capacity_(capacity == 0 ? 1 : capacity), reorder_window_s_(reorder_window_s) {}

  struct PushResult {
    std::optional<T> evicted;   // the oldest item, if the queue was full
    bool out_of_order = false;  // inserted before items already queued
    bool time_jump = false;     // older than the newest queued item by more than the window
  };

  // Inserts by `stamp` (stable for equal stamps). Returns the evicted item, if any.
  PushResult Push(double stamp, T item) {
    PushResult result;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = items_.end();
      // Against the newest stamp ever pushed, so a jump is seen even when the queue is empty.
      if (has_newest_ && newest_ - stamp > reorder_window_s_) {
        result.time_jump = true;  // appended as is; the new timeline starts here
        newest_ = stamp;
      } else {
        if (!has_newest_ || stamp > newest_) newest_ = stamp;
        // Never across a jump boundary: items far newer belong to the previous timeline.
        while (it != items_.begin() && std::prev(it)->first > stamp &&
               std::prev(it)->first - stamp <= reorder_window_s_) {
          --it;
        }
        result.out_of_order = it != items_.end();
      }
      has_newest_ = true;
      items_.insert(it, {stamp, std::move(item)});
      if (items_.size() > capacity_) {
        result.evicted = std::move(items_.front().second);
        items_.pop_front();
      }
      ++version_;
    }
    cv_.notify_one();
    return result;
  }

  // Moves everything queued into *out (in time order). Returns the number of items.
  size_t PopAll(std::deque<std::pair<double, T>>* out) {
    std::lock_guard<std::mutex> lock(mutex_);
    const size_t n = items_.size();
    for (auto& item : items_) out->push_back(std::move(item));
    items_.clear();
    return n;
  }

  // Pops the front item only if its stamp satisfies `pred`.
  template <typename Pred>
  std::optional<std::pair<double, T>> PopFrontIf(Pred pred) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (items_.empty() || !pred(items_.front().first)) return std::nullopt;
    auto item = std::move(items_.front());
    items_.pop_front();
    return item;
  }

  // A copy of the front item, left queued.
  std::optional<std::pair<double, T>> PeekFront() const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (items_.empty()) return std::nullopt;
    return items_.front();
  }

  std::optional<std::pair<double, T>> PopFront() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (items_.empty()) return std::nullopt;
    auto item = std::move(items_.front());
    items_.pop_front();
    return item;
  }

  size_t Size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_.size();
  }
  size_t capacity() const { return capacity_; }

  // Wakes the consumer (also used by Interrupt()).
  void Notify() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++version_;
    }
    cv_.notify_all();
  }

  // Blocks until something was pushed after `*seen_version` or the timeout expires.
  void WaitForChange(uint64_t* seen_version, std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, timeout, [&] { return version_ != *seen_version; });
    *seen_version = version_;
  }

 private:
  const size_t capacity_;
  const double reorder_window_s_;
  bool has_newest_ = false;
  double newest_ = 0.0;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::pair<double, T>> items_;
  uint64_t version_ = 0;
};

}  // namespace ppf::dds
