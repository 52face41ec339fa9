// Height-field ground shaped per scene: long slopes, curbs along the road, uneven lawn.
#include <algorithm>
#include <cmath>

#include "world_detail.hpp"

namespace ppf::sim::detail {

namespace {

struct Wave {
  double kx, ky, amp, phase;
};

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

  std::vector<Wave> waves;
  auto add_waves = [&](int n, double lmin, double lmax, double amin, double amax) {
    for (int k = 0; k < n; ++k) {
      const double lambda = rng.Uniform(lmin, lmax), dir = rng.Uniform(0, 2 * M_PI);
      waves.push_back({2 * M_PI / lambda * std::cos(dir), 2 * M_PI / lambda * std::sin(dir),
                       rng.Uniform(amin, amax), rng.Uniform(0, 2 * M_PI)});
    }
  };
  double vertex_noise = 0.0;
  double road_half = 0.0, raise = 0.0;
  if (scene == "urban") {
    add_waves(3, 150.0, 400.0, 0.3, 1.5);  // slopes of a few percent
    road_half = 6.0;                       // curb at 6 m from the lane centre
    raise = 0.15;                          // curb height
    hf.reflectivity_low = 0.10f;           // asphalt
    hf.reflectivity_high = 0.28f;          // pavement
  } else if (scene == "park") {
    add_waves(3, 80.0, 250.0, 0.3, 1.2);
    add_waves(5, 4.0, 20.0, 0.05, 0.25);   // uneven lawn
    vertex_noise = 0.02;
    road_half = 1.5;                       // gravel path
    hf.reflectivity_low = 0.2f;
    hf.reflectivity_high = 0.4f;           // grass is bright in the near infrared
  } else {                                 // ramps: a flat paved yard
    hf.reflectivity_low = 0.15f;
    hf.reflectivity_high = 0.15f;
  }
  // Distance to the path near it (road/curb/material), stamped from dense path points.
  std::vector<float> dist(static_cast<size_t>(nx) * ny, 1e9f);
  if (road_half > 0) {
    const double reach = road_half + 1.0;
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
  }
  Rng noise_rng(rng.NextBits());
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double x = x0 + i * cell, y = y0 + j * cell;
      double h = 0.0;
      for (const Wave& w : waves) h += w.amp * std::sin(w.kx * x + w.ky * y + w.phase);
      if (raise > 0 && dist[static_cast<size_t>(j) * nx + i] > road_half) h += raise;
      if (vertex_noise > 0) h += vertex_noise * noise_rng.Normal();
      hf.at(i, j) = static_cast<float>(h);
    }
  }
  if (road_half > 0) {
    hf.material.assign(static_cast<size_t>(nx - 1) * (ny - 1), 1);
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i)
        if (dist[static_cast<size_t>(j) * nx + i] <= road_half)
          hf.material[static_cast<size_t>(j) * (nx - 1) + i] = 0;
  }
  hf.Finalize();
  return hf;
}

}  // namespace ppf::sim::detail
