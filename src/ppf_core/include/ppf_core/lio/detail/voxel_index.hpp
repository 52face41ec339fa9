// The kNN map's table from voxel key to voxel (voxel_map.hpp), not for use elsewhere.
//
// Open addressing with linear probing (power-of-two capacity, at most half full, backward-shift
// deletion). A query looks up 7-27 voxels, most of them empty; std::unordered_map went through a
// bucket and a node for each, here a lookup reads one slot, or a few adjacent ones. Only lookups
// depend on it: nothing iterates over it, so its order changes no result.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "ppf_core/lio/voxel_key.hpp"

namespace ppf {
namespace detail {

template <typename Value>
class VoxelIndex {
 public:
  const Value* Find(const VoxelKey& k) const {
    if (size_ == 0) return nullptr;
    for (size_t i = Home(k);; i = (i + 1) & mask_) {
      const Slot& s = slots_[i];
      if (!s.used) return nullptr;
      if (s.key == k) return &s.value;
    }
  }
  // Asks the cache for the slot where a Find(k) starts (a query issues its voxels' loads at once,
  // instead of waiting on each in turn).
  void Prefetch(const VoxelKey& k) const {
    if (size_ != 0) __builtin_prefetch(&slots_[Home(k)]);
  }
  Value* Find(const VoxelKey& k) {  // valid until the next Insert or Erase
    return const_cast<Value*>(static_cast<const VoxelIndex&>(*this).Find(k));
  }
  // k must not be present. Returns its value, valid until the next Insert or Erase.
  Value* Insert(const VoxelKey& k, Value v) {
    if (2 * (size_ + 1) > slots_.size()) Grow();
    size_t i = Home(k);
    while (slots_[i].used) i = (i + 1) & mask_;
    slots_[i] = Slot{k, true, v};
    ++size_;
    return &slots_[i].value;
  }
  void Erase(const VoxelKey& k) {
    if (size_ == 0) return;
    size_t i = Home(k);
    for (;; i = (i + 1) & mask_) {
      if (!slots_[i].used) return;
      if (slots_[i].key == k) break;
    }
    // Backward shift: a later entry of the run moves into the hole when the hole lies on its
    // probe path (its distance from home is at least the hole's distance behind it).
    for (size_t j = (i + 1) & mask_; slots_[j].used; j = (j + 1) & mask_) {
      if (((j - Home(slots_[j].key)) & mask_) >= ((j - i) & mask_)) {
        slots_[i] = slots_[j];
        i = j;
      }
    }
    slots_[i] = Slot{};
    --size_;
  }
  size_t size() const { return size_; }
  void clear() {
    slots_.clear();
    mask_ = 0;
    size_ = 0;
  }

 private:
  struct Slot {
    VoxelKey key;
    bool used = false;
    Value value;
  };
  size_t Home(const VoxelKey& k) const {
    uint64_t h = static_cast<uint64_t>(static_cast<uint32_t>(k.x)) * 0x9E3779B97F4A7C15ULL ^
                 static_cast<uint64_t>(static_cast<uint32_t>(k.y)) * 0xC2B2AE3D27D4EB4FULL ^
                 static_cast<uint64_t>(static_cast<uint32_t>(k.z)) * 0x165667B19E3779F9ULL;
    h ^= h >> 32;
    return static_cast<size_t>(h) & mask_;
  }
  void Grow() {
    std::vector<Slot> old;
    old.swap(slots_);
    slots_.resize(std::max<size_t>(64, old.size() * 2));
    mask_ = slots_.size() - 1;
    size_ = 0;
    for (const Slot& s : old) {
      if (s.used) Insert(s.key, s.value);
    }
  }
  std::vector<Slot> slots_;
  size_t mask_ = 0;
  size_t size_ = 0;
};

}  // namespace detail
}  // namespace ppf
