// StallWatch: one input stream that has a matched publisher but receives nothing. A matched
// writer whose data stopped (a stalled driver, a broken shared-memory segment, a paused replay)
// looks healthy to matching alone: the node kept printing status=ok while it received nothing.
//
// Threads: the reader's listener calls OnMatched / OnSample (atomics only, never a lock, since
// Fast DDS holds its own locks there); one thread (the diagnostics loop) calls Poll and reads the
// episode state.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>

namespace ppf::dds {

class StallWatch {
 public:
  using Clock = std::chrono::steady_clock;

  enum class Event {
    kNone,
    // Silent for warn_after_s with a publisher matched. `counted`: data had flowed since the
    // publishers matched, so this is data that stopped (a replay or driver not yet sending is
    // warned about but not counted).
    kStalled,
    kStillStalled,  // the same episode, silent twice as long as at the last line
    kResumed,       // a sample arrived (or the first one, after a not-counted episode)
    kEnded,         // the last publisher left during the episode: no longer a stall
  };
  struct Poll {
    Event event = Event::kNone;
    double silent_s = 0.0;  // at the poll, or for kResumed/kEnded the longest silence seen
    bool counted = false;
  };

  // warn_after_s <= 0 disables the watch (Poll never reports).
  explicit StallWatch(double warn_after_s) : warn_after_s_(warn_after_s) {}

  void OnMatched(int current_count, Clock::time_point now) {
    const int before = matched_.exchange(current_count);
    if (current_count > 0 && before <= 0) {
      matched_since_ns_.store(Ns(now));
    } else if (current_count <= 0) {
      // A publisher matching later starts afresh: its silence before its first sample is a
      // replay or driver not yet sending, not data that stopped.
      flowed_.store(false);
    }
  }
  void OnSample(Clock::time_point now) {
    last_sample_ns_.store(Ns(now));
    flowed_.store(true);
  }

  Poll Check(Clock::time_point now) {
    Poll p;
    if (!(warn_after_s_ > 0.0)) return p;
    const int matched = matched_.load();
    const int64_t since = std::max(last_sample_ns_.load(), matched_since_ns_.load());
    const double silent = since == kNever ? 0.0 : (Ns(now) - since) * 1e-9;
    const bool silent_now = matched > 0 && silent >= warn_after_s_;
    if (!in_episode_) {
      if (!silent_now) return p;
      in_episode_ = true;
      counted_ = flowed_.load();
      longest_s_ = silent;
      next_warn_s_ = 2.0 * silent;
      p.event = Event::kStalled;
      p.silent_s = silent;
      p.counted = counted_;
      return p;
    }
    p.counted = counted_;
    if (silent_now) {
      longest_s_ = std::max(longest_s_, silent);
      p.silent_s = silent;
      if (silent >= next_warn_s_) {
        next_warn_s_ = 2.0 * silent;
        p.event = Event::kStillStalled;
      }
      return p;
    }
    in_episode_ = false;
    p.event = matched > 0 ? Event::kResumed : Event::kEnded;
    // The silence ended somewhere between this poll and the last one.
    p.silent_s = longest_s_;
    return p;
  }

  // Polling thread only: inside an episode, and whether it counts (data had flowed before).
  bool stalled() const { return in_episode_; }
  bool counted() const { return in_episode_ && counted_; }
  int matched() const { return matched_.load(); }
  double warn_after_s() const { return warn_after_s_; }

 private:
  static constexpr int64_t kNever = INT64_MIN;
  static int64_t Ns(Clock::time_point t) {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
  }

  const double warn_after_s_;
  std::atomic<int> matched_{0};
  std::atomic<int64_t> matched_since_ns_{kNever};
  std::atomic<int64_t> last_sample_ns_{kNever};
  std::atomic<bool> flowed_{false};
  // Polling thread only.
  bool in_episode_ = false;
  bool counted_ = false;
  double longest_s_ = 0.0;
  double next_warn_s_ = 0.0;
};

}  // namespace ppf::dds
