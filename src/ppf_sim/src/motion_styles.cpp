// How the platform shakes on top of its path: hand-held rotations and gait, car suspension.
#include <cmath>

#include "world_detail.hpp"

namespace ppf::sim::detail {

std::vector<Shake> HandheldShakes(Rng& rng, double max_rate_deg) {
  struct Raw {
    int ch;
    double amp, f;
  };
  const Raw raw[] = {{2, 0.30, 0.8}, {2, 0.08, 1.9}, {1, 0.15, 1.1}, {1, 0.04, 2.3},
                     {0, 0.10, 0.7}, {0, 0.03, 2.7}};
  std::vector<Shake> out;
  double peak[3] = {0, 0, 0};
  for (const Raw& r : raw) {
    Shake s{r.ch, r.amp, r.f * rng.Uniform(0.85, 1.15), rng.Uniform(0, 2 * M_PI)};
    peak[r.ch] += s.amp * 2 * M_PI * s.freq_hz;
    out.push_back(s);
  }
  const double norm = std::sqrt(peak[0] * peak[0] + peak[1] * peak[1] + peak[2] * peak[2]);
  const double scale = max_rate_deg * M_PI / 180.0 / norm;
  for (Shake& s : out) s.amp *= scale;
  out.push_back({5, 0.025, 1.8 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)});  // gait bob
  out.push_back({3, 0.015, 0.9, rng.Uniform(0, 2 * M_PI)});
  out.push_back({4, 0.015, 0.9, rng.Uniform(0, 2 * M_PI)});
  return out;
}

std::vector<Shake> CarShakes(Rng& rng) {
  return {{0, 0.004, 1.3 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)},
          {1, 0.005, 1.7 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)},
          {5, 0.008, 2.1 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)}};
}

}  // namespace ppf::sim::detail
