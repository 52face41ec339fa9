#include "ppf_sim/height_field.hpp"

#include <algorithm>
#include <cmath>

#include "grid_walk.hpp"

namespace ppf::sim {

HeightField::HeightField(double x0, double y0, double cell, int nx, int ny)
    : x0_(x0), y0_(y0), cell_(cell), nx_(nx), ny_(ny), h_(static_cast<size_t>(nx) * ny, 0.0f) {}

void HeightField::Finalize() {
  const int cx = nx_ - 1, cy = ny_ - 1;
  bx_ = (cx + kBlock - 1) / kBlock;
  by_ = (cy + kBlock - 1) / kBlock;
  block_max_.assign(static_cast<size_t>(bx_) * by_, -1e30f);
  for (int bj = 0; bj < by_; ++bj) {
    for (int bi = 0; bi < bx_; ++bi) {
      float m = -1e30f;
      for (int j = bj * kBlock; j <= std::min((bj + 1) * kBlock, ny_ - 1); ++j) {
        for (int i = bi * kBlock; i <= std::min((bi + 1) * kBlock, nx_ - 1); ++i) {
          m = std::max(m, at(i, j));
        }
      }
      block_max_[static_cast<size_t>(bj) * bx_ + bi] = m;
    }
  }
}

bool HeightField::Contains(double x, double y) const {
  return nx_ > 1 && x >= x0_ && y >= y0_ && x <= x0_ + (nx_ - 1) * cell_ &&
         y <= y0_ + (ny_ - 1) * cell_;
}

double HeightField::Height(double x, double y) const {
  if (nx_ < 2) return 0.0;
  const double gx = std::clamp((x - x0_) / cell_, 0.0, nx_ - 1.000001);
  const double gy = std::clamp((y - y0_) / cell_, 0.0, ny_ - 1.000001);
  const int i = static_cast<int>(gx), j = static_cast<int>(gy);
  const double fx = gx - i, fy = gy - j;
  const double h00 = at(i, j), h10 = at(i + 1, j), h01 = at(i, j + 1), h11 = at(i + 1, j + 1);
  if (fx >= fy) return h00 + (h10 - h00) * fx + (h11 - h10) * fy;
  return h00 + (h11 - h01) * fx + (h01 - h00) * fy;
}

bool HeightField::IntersectCell(int i, int j, const double o[3], const double d[3], double ta,
                                double tb, double* t_hit, double n[3]) const {
  const double h00 = at(i, j), h10 = at(i + 1, j), h01 = at(i, j + 1), h11 = at(i + 1, j + 1);
  const double xc = x0_ + i * cell_, yc = y0_ + j * cell_;
  const double inv = 1.0 / cell_;
  bool found = false;
  double best = tb;
  for (int tri = 0; tri < 2; ++tri) {
    const double A = tri == 0 ? h10 - h00 : h11 - h01;
    const double B = tri == 0 ? h11 - h10 : h01 - h00;
    // g(t) = z(t) - plane(x(t), y(t)) = g0 + g1 t
    const double g0 = o[2] - h00 - A * (o[0] - xc) * inv - B * (o[1] - yc) * inv;
    const double g1 = d[2] - A * d[0] * inv - B * d[1] * inv;
    if (std::abs(g1) < 1e-15) continue;
    const double t = -g0 / g1;
    if (t < ta - 1e-9 || t > best) continue;
    const double fx = (o[0] + d[0] * t - xc) * inv, fy = (o[1] + d[1] * t - yc) * inv;
    const double e = 1e-9;
    if (fx < -e || fx > 1 + e || fy < -e || fy > 1 + e) continue;
    if (tri == 0 ? fx < fy - e : fy < fx - e) continue;
    best = t;
    found = true;
    const double nn[3] = {-A * inv, -B * inv, 1.0};
    const double len = std::sqrt(nn[0] * nn[0] + nn[1] * nn[1] + 1.0);
    n[0] = nn[0] / len;
    n[1] = nn[1] / len;
    n[2] = 1.0 / len;
  }
  if (found) *t_hit = best;
  return found;
}

bool HeightField::Intersect(const double o[3], const double d[3], double tmin, double tmax,
                            double* t_hit, double n[3]) const {
  if (nx_ < 2) return false;
  const double x1 = x0_ + (nx_ - 1) * cell_, y1 = y0_ + (ny_ - 1) * cell_;
  double t0 = tmin, t1 = tmax;
  if (!ClipToRect(o[0], o[1], d[0], d[1], x0_, y0_, x1, y1, &t0, &t1)) return false;
  const double bcell = cell_ * kBlock;
  GridWalk blocks;
  blocks.Init(o[0], o[1], d[0], d[1], x0_, y0_, bcell, bx_, by_, t0);
  double t_enter = t0;
  while (t_enter <= t1 && blocks.i >= 0 && blocks.j >= 0 && blocks.i < bx_ && blocks.j < by_) {
    const double t_exit = std::min(blocks.ExitT(), t1);
    const double za = o[2] + d[2] * t_enter, zb = o[2] + d[2] * t_exit;
    if (std::min(za, zb) <= block_max_[static_cast<size_t>(blocks.j) * bx_ + blocks.i]) {
      GridWalk cells;
      cells.Init(o[0], o[1], d[0], d[1], x0_, y0_, cell_, nx_ - 1, ny_ - 1,
                 t_enter);
      double ta = t_enter;
      while (ta <= t_exit) {
        const double tb = std::min(cells.ExitT(), t_exit);
        if (cells.i < 0 || cells.j < 0 || cells.i >= nx_ - 1 || cells.j >= ny_ - 1) break;
        if (IntersectCell(cells.i, cells.j, o, d, ta, tb + 1e-9, t_hit, n)) return true;
        ta = tb;
        if (cells.ExitT() > t_exit) break;
        cells.Advance();
      }
    }
    t_enter = t_exit;
    if (blocks.ExitT() > t1) break;
    blocks.Advance();
  }
  return false;
}

}  // namespace ppf::sim
