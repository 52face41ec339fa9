// Height-field ground shaped per scene: long slopes, curbs along the road, uneven lawn.
#include <algorithm>
#include <cmath>

#include "world_detail.hpp"

namespace ppf::sim::detail {

namespace {

struct Wave {
  double kx, ky, amp, phase;
};

// The scene's ground: its waves, vertex noise, road (curb) and materials.
struct GroundStyle {
  std::vector<Wave> waves;
  double vertex_noise = 0.0;
  double road_half = 0.0;  // m from the lane centre to the curb (0: no road)
  double raise = 0.0;      // curb height
  float reflectivity_low = 0.15f, reflectivity_high = 0.15f;
};

// Draws from `rng` in the same order for the same scene (the world is seeded).
GroundStyle StyleOf(const std::string& scene, Rng& rng) {
  GroundStyle g;
  auto add_waves = [&](int n, double lmin, double lmax, double amin, double amax) {
    for (int k = 0; k < n; ++k) {
      const double lambda = rng.Uniform(lmin, lmax), dir = rng.Uniform(0, 2 * M_PI);
      g.waves.push_back({2 * M_PI / lambda * std::cos(dir), 2 * M_PI / lambda * std::sin(dir),
                         rng.Uniform(amin, amax), rng.Uniform(0, 2 * M_PI)});
    }
  };
  if (scene == "urban") {
    add_waves(3, 150.0, 400.0, 0.3, 1.5);  // slopes of a few percent
    g.road_half = 6.0;                     // curb at 6 m from the lane centre
    g.raise = 0.15;                        // curb height
    g.reflectivity_low = 0.10f;            // asphalt
    g.reflectivity_high = 0.28f;           // pavement
  } else if (scene == "park") {
    add_waves(3, 80.0, 250.0, 0.3, 1.2);
    add_waves(5, 4.0, 20.0, 0.05, 0.25);   // uneven lawn
    g.vertex_noise = 0.02;
    g.road_half = 1.5;                     // gravel path
    g.reflectivity_low = 0.2f;
    g.reflectivity_high = 0.4f;            // grass is bright in the near infrared
  }                                        // else ramps: a flat paved yard
  return g;
}

// Distance from each vertex of the grid to the path, where it is within `reach` (road, curb,
// material); 1e9 elsewhere. Stamped from path points 0.5 m apart.
std::vector<float> DistanceToPath(const std::vector<PathSample>& path, double x0, double y0,
                                  double cell, int nx, int ny, double reach) {
  std::vector<float> dist(static_cast<size_t>(nx) * ny, 1e9f);
  const int rc = static_cast<int>(std::ceil(reach / cell));
  for (size_t s = 0; s < path.size(); ++s) {
    const PathSample& a = path[s];
    const PathSample& b = path[std::min(s + 1, path.size() - 1)];
    const int n = std::max(1, static_cast<int>(std::ceil(std::hypot(b.x - a.x, b.y - a.y) / 0.5)));
    for (int k = 0; k < n; ++k) {
      const double px = a.x + (b.x - a.x) * k / n, py = a.y + (b.y - a.y) * k / n;
      const int ci = static_cast<int>((px - x0) / cell), cj = static_cast<int>((py - y0) / cell);
      for (int j = std::max(0, cj - rc); j <= std::min(ny - 1, cj + rc); ++j) {
        for (int i = std::max(0, ci - rc); i <= std::min(nx - 1, ci + rc); ++i) {
          const float d = static_cast<float>(std::hypot(x0 + i * cell - px, y0 + j * cell - py));
          float& slot = dist[static_cast<size_t>(j) * nx + i];
          slot = std::min(slot, d);
        }
      }
    }
  }
  return dist;
}

}  // namespace

HeightField MakeTerrain(const std::vector<PathSample>& path, const std::string& scene, Rng& rng,
                        double margin) {
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const auto& p : path) {
    x0 = std::min(x0, p.x);
    y0 = std::min(y0, p.y);
    x1 = std::max(x1, p.x);
    y1 = std::max(y1, p.y);
  }
  const double cell = 0.25;
  x0 -= margin;
  y0 -= margin;
  x1 += margin;
  y1 += margin;
  const int nx = static_cast<int>(std::ceil((x1 - x0) / cell)) + 1;
  const int ny = static_cast<int>(std::ceil((y1 - y0) / cell)) + 1;
  HeightField hf(x0, y0, cell, nx, ny);

  const GroundStyle g = StyleOf(scene, rng);
  hf.reflectivity_low = g.reflectivity_low;
  hf.reflectivity_high = g.reflectivity_high;
  const std::vector<float> dist =
      g.road_half > 0 ? DistanceToPath(path, x0, y0, cell, nx, ny, g.road_half + 1.0)
                      : std::vector<float>(static_cast<size_t>(nx) * ny, 1e9f);
  Rng noise_rng(rng.NextBits());
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double x = x0 + i * cell, y = y0 + j * cell;
      double h = 0.0;
      for (const Wave& w : g.waves) h += w.amp * std::sin(w.kx * x + w.ky * y + w.phase);
      if (g.raise > 0 && dist[static_cast<size_t>(j) * nx + i] > g.road_half) h += g.raise;
      if (g.vertex_noise > 0) h += g.vertex_noise * noise_rng.Normal();
      hf.at(i, j) = static_cast<float>(h);
    }
  }
  if (g.road_half > 0) {
    hf.material.assign(static_cast<size_t>(nx - 1) * (ny - 1), 1);
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i)
        if (dist[static_cast<size_t>(j) * nx + i] <= g.road_half)
          hf.material[static_cast<size_t>(j) * (nx - 1) + i] = 0;
  }
  hf.Finalize();
  return hf;
}

}  // namespace ppf::sim::detail
