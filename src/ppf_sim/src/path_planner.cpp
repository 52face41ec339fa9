#include "ppf_sim/path_planner.hpp"

#include <algorithm>
#include <cmath>

namespace ppf::sim {

std::vector<PathSample> PlanOpenPath(const KinematicLimits& lim, double dt, int n_samples,
                                     double move_time, Rng& rng) {
  std::vector<PathSample> out;
  out.reserve(n_samples);
  const double h = 0.002;  // integration step
  double x = 0, y = 0, yaw = 0, v = 0, kappa = 0;
  enum { kStraight, kTurn } mode = kStraight;
  double remaining = rng.Uniform(lim.straight_min * 0.5, lim.straight_max * 0.5);
  double cruise = lim.cruise_speed;
  double turn_kappa = 0, turn_left = 0;
  auto plan_turn = [&]() {
    double sign = rng.Uniform() < 0.5 ? -1.0 : 1.0;
    double angle = rng.Uniform(35.0, 100.0) * M_PI / 180.0;
    const double r = std::hypot(x, y);
    if (r > lim.world_radius) {
      // Turn towards the origin, by about the angle that points back at it.
      const double to_origin = std::atan2(-y, -x);
      double diff = std::remainder(to_origin - yaw, 2.0 * M_PI);
      sign = diff >= 0 ? 1.0 : -1.0;
      angle = std::clamp(std::abs(diff), 30.0 * M_PI / 180.0, 150.0 * M_PI / 180.0);
    }
    turn_kappa = sign * rng.Uniform(0.4, 1.0) * lim.max_curvature;
    turn_left = angle;
  };
  plan_turn();
  double t = -dt;
  double next_sample = -dt;
  while (static_cast<int>(out.size()) < n_samples) {
    if (t >= next_sample - 1e-12) {
      out.push_back({x, y, yaw, v});
      next_sample += dt;
    }
    if (t < move_time) {
      t += h;
      continue;
    }
    const double v_turn =
        std::min(cruise, std::sqrt(lim.lateral_accel / std::abs(turn_kappa)));
    double v_target = cruise;
    double kappa_target = 0.0;
    if (mode == kStraight) {
      v_target = std::min(cruise, std::sqrt(v_turn * v_turn + 2.0 * lim.accel *
                                                                 std::max(remaining, 0.0)));
      if (remaining <= 0.0) mode = kTurn;
    }
    if (mode == kTurn) {
      v_target = v_turn;
      kappa_target = turn_kappa;
      // Start unwinding early so the heading change ends where planned.
      const double unwind = kappa * kappa / (2.0 * lim.curvature_rate);
      if (turn_left <= unwind) {
        kappa_target = 0.0;
        if (std::abs(kappa) < 1e-6) {
          mode = kStraight;
          remaining = rng.Uniform(lim.straight_min, lim.straight_max);
          cruise = lim.cruise_speed * rng.Uniform(0.8, 1.2);
          plan_turn();
        }
      }
    }
    const double dv = std::clamp(v_target - v, -lim.accel * h, lim.accel * h);
    v += dv;
    const double dk = lim.curvature_rate * std::max(v, 0.1) * h;
    kappa += std::clamp(kappa_target - kappa, -dk, dk);
    const double ds = v * h;
    const double dyaw = kappa * ds;
    yaw += dyaw;
    if (mode == kTurn) turn_left -= std::abs(dyaw);
    x += ds * std::cos(yaw);
    y += ds * std::sin(yaw);
    if (mode == kStraight) remaining -= ds;
    t += h;
  }
  return out;
}

namespace {

struct Dense {
  std::vector<double> x, y, s;  // points and arc length
};

Dense RoundedPolyline(const std::vector<std::pair<double, double>>& pts, double radius) {
  Dense d;
  auto add = [&d](double x, double y) {
    if (!d.x.empty()) {
      const double ds = std::hypot(x - d.x.back(), y - d.y.back());
      if (ds < 1e-9) return;
      d.s.push_back(d.s.back() + ds);
    } else {
      d.s.push_back(0.0);
    }
    d.x.push_back(x);
    d.y.push_back(y);
  };
  const double step = 0.02;
  add(pts[0].first, pts[0].second);
  for (size_t i = 1; i < pts.size(); ++i) {
    const double ax = pts[i - 1].first, ay = pts[i - 1].second;
    const double bx = pts[i].first, by = pts[i].second;
    double ex = bx, ey = by;  // where the straight part of this segment ends
    double arc_r = 0, turn = 0, ux = 0, uy = 0, wx = 0, wy = 0, trim = 0;
    if (i + 1 < pts.size()) {
      const double cx = pts[i + 1].first, cy = pts[i + 1].second;
      const double l1 = std::hypot(bx - ax, by - ay), l2 = std::hypot(cx - bx, cy - by);
      ux = (bx - ax) / l1;
      uy = (by - ay) / l1;
      wx = (cx - bx) / l2;
      wy = (cy - by) / l2;
      turn = std::atan2(ux * wy - uy * wx, ux * wx + uy * wy);
      if (std::abs(turn) > 1e-6) {
        trim = std::min({radius * std::tan(std::abs(turn) / 2), 0.45 * l1, 0.45 * l2});
        arc_r = trim / std::tan(std::abs(turn) / 2);
        ex = bx - ux * trim;
        ey = by - uy * trim;
      }
    }
    const double sx = d.x.back(), sy = d.y.back();
    const double len = std::hypot(ex - sx, ey - sy);
    const int n = std::max(1, static_cast<int>(std::ceil(len / step)));
    for (int k = 1; k <= n; ++k) add(sx + (ex - sx) * k / n, sy + (ey - sy) * k / n);
    if (arc_r > 0) {
      const double sign = turn > 0 ? 1.0 : -1.0;
      const double ccx = ex - sign * uy * arc_r, ccy = ey + sign * ux * arc_r;
      const double a0 = std::atan2(ey - ccy, ex - ccx);
      const int m = std::max(2, static_cast<int>(std::ceil(arc_r * std::abs(turn) / step)));
      for (int k = 1; k <= m; ++k) {
        const double a = a0 + turn * k / m;
        add(ccx + arc_r * std::cos(a), ccy + arc_r * std::sin(a));
      }
    }
  }
  return d;
}

}  // namespace

std::vector<PathSample> FollowPolyline(const std::vector<std::pair<double, double>>& pts,
                                       double corner_radius, double speed, double accel,
                                       double dt, int n_samples, double move_time) {
  const Dense d = RoundedPolyline(pts, corner_radius);
  const double total = d.s.back();
  std::vector<PathSample> out;
  out.reserve(n_samples);
  double s = 0, v = 0, yaw_prev = 0;
  size_t seg = 0;
  bool first = true;
  for (int i = 0; i < n_samples; ++i) {
    const double t = (i - 1) * dt;
    if (t > move_time) {
      const double v_new = std::min(speed, v + accel * dt);
      s += 0.5 * (v + v_new) * dt;
      v = v_new;
    }
    // Past the end the walker stops (callers pass a polyline long enough for the duration).
    const double q = std::min(s, total);
    while (seg + 1 < d.s.size() && d.s[seg + 1] < q) ++seg;
    const size_t nxt = std::min(seg + 1, d.s.size() - 1);
    const double f = nxt == seg ? 0.0 : (q - d.s[seg]) / (d.s[nxt] - d.s[seg]);
    PathSample p;
    p.x = d.x[seg] + f * (d.x[nxt] - d.x[seg]);
    p.y = d.y[seg] + f * (d.y[nxt] - d.y[seg]);
    const size_t a = nxt == seg && seg > 0 ? seg - 1 : seg;
    double yaw = std::atan2(d.y[nxt] - d.y[a], d.x[nxt] - d.x[a]);
    if (first) {
      yaw_prev = yaw;
      first = false;
    }
    yaw = yaw_prev + std::remainder(yaw - yaw_prev, 2.0 * M_PI);
    yaw_prev = yaw;
    p.yaw = yaw;
    p.speed = v;
    out.push_back(p);
  }
  return out;
}

void SmoothYaw(std::vector<PathSample>& path, double dt, double half_window) {
  const int w = std::max(0, static_cast<int>(std::round(half_window / dt)));
  if (w == 0 || path.empty()) return;
  std::vector<double> src(path.size());
  for (size_t i = 0; i < path.size(); ++i) src[i] = path[i].yaw;
  const int n = static_cast<int>(path.size());
  for (int i = 0; i < n; ++i) {
    double sum = 0;
    int cnt = 0;
    for (int k = std::max(0, i - w); k <= std::min(n - 1, i + w); ++k) {
      sum += src[k];
      ++cnt;
    }
    path[i].yaw = sum / cnt;
  }
}

}  // namespace ppf::sim
