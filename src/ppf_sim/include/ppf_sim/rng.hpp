// Counter-based random numbers: every draw is a pure function of (seed, stream ids), so the
// result does not depend on thread scheduling or on how many draws happened before. That is
// what makes an OpenMP-parallel scan byte-identical for a given seed.
#pragma once

#include <cmath>
#include <cstdint>

namespace ppf::sim {

inline uint64_t SplitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

inline uint64_t HashKey(uint64_t a, uint64_t b = 0, uint64_t c = 0, uint64_t d = 0) {
  uint64_t h = SplitMix64(a);
  h = SplitMix64(h ^ b);
  h = SplitMix64(h ^ c);
  return SplitMix64(h ^ d);
}

// Uniform in [0, 1) from 53 random bits.
inline double ToUnit(uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

// A small sequential generator for scene building and IMU noise (single-threaded users).
class Rng {
 public:
  explicit Rng(uint64_t seed, uint64_t stream = 0) : state_(HashKey(seed, stream, 0x51u)) {}
  uint64_t NextBits() { return SplitMix64(state_++); }
  double Uniform() { return ToUnit(NextBits()); }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  int UniformInt(int lo, int hi_inclusive) {
    return lo + static_cast<int>(Uniform() * (hi_inclusive - lo + 1));
  }
  // Box-Muller written out so the sequence is identical with every standard library.
  double Normal() {
    double u1 = Uniform();
    if (u1 < 1e-300) u1 = 1e-300;
    const double u2 = Uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }
  double Normal(double mean, double stddev) { return mean + stddev * Normal(); }

 private:
  uint64_t state_;
};

// Stateless draws keyed by a per-ray hash.
inline double KeyedUniform(uint64_t key, uint64_t salt) { return ToUnit(SplitMix64(key ^ (salt * 0xD6E8FEB86659FD93ull))); }
inline double KeyedNormal(uint64_t key, uint64_t salt) {
  double u1 = KeyedUniform(key, salt * 2 + 1);
  if (u1 < 1e-300) u1 = 1e-300;
  const double u2 = KeyedUniform(key, salt * 2 + 2);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace ppf::sim
