// 2-D digital differential analyser: visits the x-y cells a ray crosses, in order.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

namespace ppf::sim {

struct GridWalk {
  int i = 0, j = 0, si = 1, sj = 1;
  double t_next_x = 0, t_next_y = 0, dt_x = 0, dt_y = 0;

  // Starts at ray parameter t0 (the ray must be inside the grid there). Cells are clamped to
  // [0, nx) x [0, ny) to absorb rounding at the border.
  void Init(double ox, double oy, double dx, double dy, double gx0, double gy0, double cell,
            int nx, int ny, double t0) {
    const double inf = std::numeric_limits<double>::infinity();
    const double px = ox + dx * t0, py = oy + dy * t0;
    i = std::clamp(static_cast<int>(std::floor((px - gx0) / cell)), 0, nx - 1);
    j = std::clamp(static_cast<int>(std::floor((py - gy0) / cell)), 0, ny - 1);
    si = dx > 0 ? 1 : -1;
    sj = dy > 0 ? 1 : -1;
    if (std::abs(dx) > 1e-12) {
      const double bx = gx0 + (i + (dx > 0 ? 1 : 0)) * cell;
      t_next_x = t0 + (bx - px) / dx;
      dt_x = cell / std::abs(dx);
    } else {
      t_next_x = inf;
      dt_x = inf;
    }
    if (std::abs(dy) > 1e-12) {
      const double by = gy0 + (j + (dy > 0 ? 1 : 0)) * cell;
      t_next_y = t0 + (by - py) / dy;
      dt_y = cell / std::abs(dy);
    } else {
      t_next_y = inf;
      dt_y = inf;
    }
  }
  // Ray parameter where the current cell is left.
  double ExitT() const { return std::min(t_next_x, t_next_y); }
  void Advance() {
    if (t_next_x < t_next_y) {
      i += si;
      t_next_x += dt_x;
    } else {
      j += sj;
      t_next_y += dt_y;
    }
  }
};

// Ray parameter interval inside the axis-aligned x-y rectangle; false if it misses.
inline bool ClipToRect(double ox, double oy, double dx, double dy, double x0, double y0,
                       double x1, double y1, double* tmin, double* tmax) {
  const double o[2] = {ox, oy}, d[2] = {dx, dy}, lo[2] = {x0, y0}, hi[2] = {x1, y1};
  for (int k = 0; k < 2; ++k) {
    if (std::abs(d[k]) < 1e-12) {
      if (o[k] < lo[k] || o[k] > hi[k]) return false;
      continue;
    }
    double ta = (lo[k] - o[k]) / d[k], tb = (hi[k] - o[k]) / d[k];
    if (ta > tb) std::swap(ta, tb);
    *tmin = std::max(*tmin, ta);
    *tmax = std::min(*tmax, tb);
  }
  return *tmin <= *tmax;
}

}  // namespace ppf::sim
