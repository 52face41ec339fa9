#include "ppf_sim/scene.hpp"

#include <algorithm>
#include <cmath>

#include "grid_walk.hpp"
#include "ppf_sim/rng.hpp"

namespace ppf::sim {

Primitive MakeQuad(const Eigen::Vector3d& center, const Eigen::Vector3d& axis_u, double half_u,
                   const Eigen::Vector3d& axis_v, double half_v, float reflectivity) {
  Primitive p;
  p.kind = PrimKind::kQuad;
  p.c = center;
  p.u = axis_u.normalized();
  p.v = axis_v.normalized();
  p.n = p.u.cross(p.v).normalized();
  p.half = {half_u, half_v, 0.0};
  p.reflectivity = reflectivity;
  return p;
}

Primitive MakeBox(double cx, double cy, double yaw, double half_x, double half_y, double z0,
                  double z1, float reflectivity) {
  Primitive p;
  p.kind = PrimKind::kBox;
  p.c = {cx, cy, 0.5 * (z0 + z1)};
  p.u = {std::cos(yaw), std::sin(yaw), 0.0};
  p.v = {-std::sin(yaw), std::cos(yaw), 0.0};
  p.half = {half_x, half_y, 0.5 * (z1 - z0)};
  p.reflectivity = reflectivity;
  return p;
}

Primitive MakeCylinder(double cx, double cy, double radius, double z0, double z1,
                       float reflectivity) {
  Primitive p;
  p.kind = PrimKind::kCylinder;
  p.c = {cx, cy, 0.5 * (z0 + z1)};
  p.half = {radius, radius, 0.5 * (z1 - z0)};
  p.reflectivity = reflectivity;
  return p;
}

Primitive MakeBlob(const Eigen::Vector3d& center, const Eigen::Vector3d& radii, float reflectivity,
                   float scatter_depth, float gap) {
  Primitive p;
  p.kind = PrimKind::kBlob;
  p.c = center;
  p.half = radii;
  p.reflectivity = reflectivity;
  p.scatter_depth = scatter_depth;
  p.gap = gap;
  return p;
}

namespace {

bool IntersectQuad(const Primitive& p, const Ray& ray, double tmax, Hit* hit) {
  const Eigen::Vector3d& o = ray.o;
  const Eigen::Vector3d& d = ray.d;
  const double den = d.dot(p.n);
  if (std::abs(den) < 1e-12) return false;
  const double t = (p.c - o).dot(p.n) / den;
  if (t <= ray.tmin || t >= tmax) return false;
  const Eigen::Vector3d q = o + t * d - p.c;
  if (std::abs(q.dot(p.u)) > p.half.x() || std::abs(q.dot(p.v)) > p.half.y()) return false;
  hit->t = t;
  hit->n = p.n;
  return true;
}

// Slabs in the box's own axes (u, v, z).
bool IntersectBox(const Primitive& p, const Ray& ray, double tmax, Hit* hit) {
  const Eigen::Vector3d& o = ray.o;
  const Eigen::Vector3d& d = ray.d;
  const Eigen::Vector3d rel = o - p.c;
  const double lo[3] = {rel.dot(p.u), rel.dot(p.v), rel.z()};
  const double ld[3] = {d.dot(p.u), d.dot(p.v), d.z()};
  double tn = -1e300, tf = 1e300;
  int axis = 0;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(ld[k]) < 1e-12) {
      if (std::abs(lo[k]) > p.half[k]) return false;
      continue;
    }
    double ta = (-p.half[k] - lo[k]) / ld[k], tb = (p.half[k] - lo[k]) / ld[k];
    if (ta > tb) std::swap(ta, tb);
    if (ta > tn) {
      tn = ta;
      axis = k;
    }
    tf = std::min(tf, tb);
  }
  if (tn > tf || tn <= ray.tmin || tn >= tmax) return false;
  hit->t = tn;
  hit->n = axis == 0 ? p.u : axis == 1 ? p.v : Eigen::Vector3d::UnitZ();
  return true;
}

// The mantle, then the top cap (the bottom stands on the ground).
bool IntersectCylinder(const Primitive& p, const Ray& ray, double tmax, Hit* hit) {
  const Eigen::Vector3d& o = ray.o;
  const Eigen::Vector3d& d = ray.d;
  const double r = p.half.x();
  const double ox = o.x() - p.c.x(), oy = o.y() - p.c.y();
  bool found = false;
  double best = tmax;
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 1e-12) {
    const double b = ox * d.x() + oy * d.y();
    const double c = ox * ox + oy * oy - r * r;
    const double disc = b * b - a * c;
    if (disc >= 0.0) {
      const double t = (-b - std::sqrt(disc)) / a;
      const double z = o.z() + t * d.z() - p.c.z();
      if (t > ray.tmin && t < best && std::abs(z) <= p.half.z()) {
        best = t;
        found = true;
        hit->n = Eigen::Vector3d(ox + t * d.x(), oy + t * d.y(), 0.0) / r;
      }
    }
  }
  if (std::abs(d.z()) > 1e-12) {  // top cap
    const double t = (p.c.z() + p.half.z() - o.z()) / d.z();
    const double x = ox + t * d.x(), y = oy + t * d.y();
    if (t > ray.tmin && t < best && x * x + y * y <= r * r) {
      best = t;
      found = true;
      hit->n = Eigen::Vector3d::UnitZ();
    }
  }
  if (found) hit->t = best;
  return found;
}

bool IntersectBlob(const Primitive& p, const Ray& ray, double tmax, uint32_t salt, Hit* hit) {
  const Eigen::Vector3d& o = ray.o;
  const Eigen::Vector3d& d = ray.d;
  const Eigen::Vector3d os = (o - p.c).cwiseQuotient(p.half);
  const Eigen::Vector3d ds = d.cwiseQuotient(p.half);
  const double a = ds.squaredNorm(), b = os.dot(ds), c = os.squaredNorm() - 1.0;
  const double disc = b * b - a * c;
  if (disc < 0.0) return false;
  const double sq = std::sqrt(disc);
  double t_in = (-b - sq) / a;
  const double t_out = (-b + sq) / a;
  if (t_out <= ray.tmin || t_in >= tmax) return false;
  t_in = std::max(t_in, ray.tmin);
  // Foliage: the beam either finds a gap or is stopped at a random depth inside.
  if (KeyedUniform(ray.key, 3ull * salt + 11) < p.gap) return false;
  const double u = KeyedUniform(ray.key, 3ull * salt + 12);
  const double t = t_in - p.scatter_depth * std::log(1.0 - u);
  if (t >= t_out || t >= tmax) return false;
  hit->t = t;
  const Eigen::Vector3d q = (o + t * d - p.c).cwiseQuotient(p.half.cwiseProduct(p.half));
  hit->n = q.normalized();
  return true;
}

}  // namespace

bool IntersectPrimitive(const Primitive& p, const Ray& ray, double tmax, uint32_t salt,
                        Hit* hit) {
  switch (p.kind) {
    case PrimKind::kQuad:
      return IntersectQuad(p, ray, tmax, hit);
    case PrimKind::kBox:
      return IntersectBox(p, ray, tmax, hit);
    case PrimKind::kCylinder:
      return IntersectCylinder(p, ray, tmax, hit);
    case PrimKind::kBlob:
      return IntersectBlob(p, ray, tmax, salt, hit);
  }
  return false;
}

namespace {

void XyBounds(const Primitive& p, double* x0, double* y0, double* x1, double* y1) {
  double ex = 0, ey = 0;
  switch (p.kind) {
    case PrimKind::kQuad:
      ex = std::abs(p.u.x()) * p.half.x() + std::abs(p.v.x()) * p.half.y();
      ey = std::abs(p.u.y()) * p.half.x() + std::abs(p.v.y()) * p.half.y();
      break;
    case PrimKind::kBox:
      ex = std::abs(p.u.x()) * p.half.x() + std::abs(p.v.x()) * p.half.y();
      ey = std::abs(p.u.y()) * p.half.x() + std::abs(p.v.y()) * p.half.y();
      break;
    case PrimKind::kCylinder:
      ex = ey = p.half.x();
      break;
    case PrimKind::kBlob:
      ex = p.half.x();
      ey = p.half.y();
      break;
  }
  *x0 = p.c.x() - ex - 1e-6;
  *x1 = p.c.x() + ex + 1e-6;
  *y0 = p.c.y() - ey - 1e-6;
  *y1 = p.c.y() + ey + 1e-6;
}

constexpr double kGlobalExtent = 150.0;  // larger primitives are tested by every ray

}  // namespace

void Scene::Build(double cell_size) {
  cell_ = cell_size;
  global_.clear();
  double bx0 = 1e300, by0 = 1e300, bx1 = -1e300, by1 = -1e300;
  std::vector<uint32_t> local;
  for (uint32_t k = 0; k < prims_.size(); ++k) {
    double x0, y0, x1, y1;
    XyBounds(prims_[k], &x0, &y0, &x1, &y1);
    if (x1 - x0 > kGlobalExtent || y1 - y0 > kGlobalExtent) {
      global_.push_back(k);
      continue;
    }
    local.push_back(k);
    bx0 = std::min(bx0, x0);
    by0 = std::min(by0, y0);
    bx1 = std::max(bx1, x1);
    by1 = std::max(by1, y1);
  }
  if (local.empty()) {
    nx_ = ny_ = 0;
    cell_start_.assign(1, 0);
    cell_items_.clear();
    return;
  }
  x0_ = bx0;
  y0_ = by0;
  nx_ = std::max(1, static_cast<int>(std::ceil((bx1 - bx0) / cell_)));
  ny_ = std::max(1, static_cast<int>(std::ceil((by1 - by0) / cell_)));
  std::vector<uint32_t> count(static_cast<size_t>(nx_) * ny_ + 1, 0);
  auto range = [&](uint32_t k, int* i0, int* j0, int* i1, int* j1) {
    double x0, y0, x1, y1;
    XyBounds(prims_[k], &x0, &y0, &x1, &y1);
    *i0 = std::clamp(static_cast<int>(std::floor((x0 - x0_) / cell_)), 0, nx_ - 1);
    *i1 = std::clamp(static_cast<int>(std::floor((x1 - x0_) / cell_)), 0, nx_ - 1);
    *j0 = std::clamp(static_cast<int>(std::floor((y0 - y0_) / cell_)), 0, ny_ - 1);
    *j1 = std::clamp(static_cast<int>(std::floor((y1 - y0_) / cell_)), 0, ny_ - 1);
  };
  for (uint32_t k : local) {
    int i0, j0, i1, j1;
    range(k, &i0, &j0, &i1, &j1);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) ++count[static_cast<size_t>(j) * nx_ + i + 1];
  }
  for (size_t c = 1; c < count.size(); ++c) count[c] += count[c - 1];
  cell_start_ = count;
  cell_items_.assign(count.back(), 0);
  std::vector<uint32_t> fill(count.begin(), count.end() - 1);
  for (uint32_t k : local) {
    int i0, j0, i1, j1;
    range(k, &i0, &j0, &i1, &j1);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) cell_items_[fill[static_cast<size_t>(j) * nx_ + i]++] = k;
  }
}

double Scene::GroundHeight(double x, double y) const {
  return has_ground_ ? ground_.Height(x, y) : 0.0;
}

bool Scene::Intersect(const Ray& ray, Hit* hit) const {
  double best = ray.tmax;
  bool found = false;
  Hit h;
  if (has_ground_) {
    const double o[3] = {ray.o.x(), ray.o.y(), ray.o.z()};
    const double d[3] = {ray.d.x(), ray.d.y(), ray.d.z()};
    double t, n[3];
    if (ground_.Intersect(o, d, ray.tmin, best, &t, n)) {
      best = t;
      found = true;
      hit->t = t;
      hit->n = Eigen::Vector3d(n[0], n[1], n[2]);
      hit->prim = -1;
      const Eigen::Vector3d q = ray.o + t * ray.d;
      hit->reflectivity = ground_.reflectivity_low;
      if (!ground_.material.empty()) {
        const int i = std::clamp(static_cast<int>((q.x() - ground_.x0()) / ground_.cell()), 0,
                                 ground_.nx() - 2);
        const int j = std::clamp(static_cast<int>((q.y() - ground_.y0()) / ground_.cell()), 0,
                                 ground_.ny() - 2);
        if (ground_.material[static_cast<size_t>(j) * (ground_.nx() - 1) + i])
          hit->reflectivity = ground_.reflectivity_high;
      }
    }
  }
  for (uint32_t k : global_) {
    if (IntersectPrimitive(prims_[k], ray, best, k, &h)) {
      best = h.t;
      found = true;
      *hit = h;
      hit->prim = static_cast<int32_t>(k);
      hit->reflectivity = prims_[k].reflectivity;
    }
  }
  if (nx_ == 0) return found;
  double t0 = ray.tmin, t1 = best;
  if (!ClipToRect(ray.o.x(), ray.o.y(), ray.d.x(), ray.d.y(), x0_, y0_, x0_ + nx_ * cell_,
                  y0_ + ny_ * cell_, &t0, &t1)) {
    return found;
  }
  GridWalk walk;
  walk.Init(ray.o.x(), ray.o.y(), ray.d.x(), ray.d.y(), x0_, y0_, cell_, nx_, ny_, t0);
  while (walk.i >= 0 && walk.j >= 0 && walk.i < nx_ && walk.j < ny_) {
    const size_t c = static_cast<size_t>(walk.j) * nx_ + walk.i;
    for (uint32_t s = cell_start_[c]; s < cell_start_[c + 1]; ++s) {
      const uint32_t k = cell_items_[s];
      if (IntersectPrimitive(prims_[k], ray, best, k, &h)) {
        best = h.t;
        found = true;
        *hit = h;
        hit->prim = static_cast<int32_t>(k);
        hit->reflectivity = prims_[k].reflectivity;
      }
    }
    const double t_exit = walk.ExitT();
    if (best <= t_exit || t_exit > t1) break;
    walk.Advance();
  }
  return found;
}

}  // namespace ppf::sim
