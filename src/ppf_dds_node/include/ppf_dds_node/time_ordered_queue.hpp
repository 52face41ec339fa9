// Bounded, time-ordered hand-over queue between DDS listener threads (producers) and the core's
// executor thread (consumer). Push never blocks: a listener thread must not wait for the core.
// When full, the OLDEST item is evicted and returned to the caller, which counts/logs it.
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
  explicit TimeOrderedQueue(size_t capacity) : capacity_(capacity == 0 ? 1 : capacity) {}

  struct PushResult {
    std::optional<T> evicted;  // the oldest item, if the queue was full
    bool out_of_order = false; // inserted before items already queued
  };

  // Inserts by `stamp` (stable for equal stamps). Returns the evicted item, if any.
  PushResult Push(double stamp, T item) {
    PushResult result;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = items_.end();
      while (it != items_.begin() && std::prev(it)->first > stamp) --it;
      result.out_of_order = it != items_.end();
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
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::pair<double, T>> items_;
  uint64_t version_ = 0;
};

}  // namespace ppf::dds
