#include "ppf_trajectory/evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <Eigen/SVD>

namespace ppf {

ErrorStats ComputeStats(const std::vector<double>& e) {
  ErrorStats s;
  s.count = e.size();
  if (e.empty()) return s;
  std::vector<double> sorted = e;
  std::sort(sorted.begin(), sorted.end());
  double sum = 0.0, sse = 0.0;
  for (double x : e) {
    sum += x;
    sse += x * x;
  }
  const double n = static_cast<double>(e.size());
  s.sse = sse;
  s.mean = sum / n;
  s.rmse = std::sqrt(sse / n);
  double var = 0.0;
  for (double x : e) var += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(var / n);  // population std, as numpy's default used by evo
  s.min = sorted.front();
  s.max = sorted.back();
  const size_t m = sorted.size() / 2;
  s.median = sorted.size() % 2 ? sorted[m] : 0.5 * (sorted[m - 1] + sorted[m]);
  return s;
}

std::vector<std::pair<size_t, size_t>> AssociateByStamp(const Trajectory& ref,
                                                        const Trajectory& est, double max_diff,
                                                        double offset) {
  // evo iterates over the shorter trajectory and picks, for each of its stamps, the nearest stamp
  // of the longer one (first one on ties); the offset is added to the estimate's stamps.
  std::vector<std::pair<size_t, size_t>> out;
  if (ref.empty() || est.empty()) return out;
  const bool est_longer = est.size() > ref.size();
  const Trajectory& shorter = est_longer ? ref : est;
  const Trajectory& longer = est_longer ? est : ref;
  const double off_long = est_longer ? offset : 0.0;
  const double off_short = est_longer ? 0.0 : offset;
  for (size_t i = 0; i < shorter.size(); ++i) {
    const double t = shorter[i].stamp_s + off_short;
    size_t best = 0;
    double best_d = std::abs(longer[0].stamp_s + off_long - t);
    for (size_t j = 1; j < longer.size(); ++j) {
      const double d = std::abs(longer[j].stamp_s + off_long - t);
      if (d < best_d) {
        best_d = d;
        best = j;
      }
    }
    if (best_d <= max_diff) {
      out.emplace_back(est_longer ? i : best, est_longer ? best : i);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

namespace {

Eigen::Vector3d Mean(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) m += p;
  return m / static_cast<double>(points.size());
}

}  // namespace

bool Umeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
             bool with_scale, Eigen::Matrix3d* R, Eigen::Vector3d* t, double* scale) {
  const size_t n = src.size();
  if (n < 3 || dst.size() != n) return false;
  const Eigen::Vector3d ms = Mean(src), md = Mean(dst);
  double var_s = 0.0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    var_s += (src[i] - ms).squaredNorm();
    cov += (dst[i] - md) * (src[i] - ms).transpose();
  }
  var_s /= static_cast<double>(n);
  cov /= static_cast<double>(n);
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(0) > 0.0) || sv(1) < 1e-12 * sv(0)) return false;  // collinear points: R undefined
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;
  *R = svd.matrixU() * S * svd.matrixV().transpose();
  *scale = with_scale ? (sv.asDiagonal() * S).trace() / var_s : 1.0;
  *t = md - *scale * (*R) * ms;
  return true;
}

bool AlignPositionYaw(const std::vector<Eigen::Vector3d>& src,
                      const std::vector<Eigen::Vector3d>& dst, Eigen::Matrix3d* R,
                      Eigen::Vector3d* t) {
  const size_t n = src.size();
  if (n < 2 || dst.size() != n) return false;
  const Eigen::Vector3d ms = Mean(src), md = Mean(dst);
  // With R = Rz(yaw), sum |d - R s|^2 over the centred points depends on yaw only through
  // -2 (cos(yaw) C + sin(yaw) S); z does not rotate, so only x and y enter C and S.
  double c = 0.0, s = 0.0, spread = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = src[i] - ms, b = dst[i] - md;
    c += a.x() * b.x() + a.y() * b.y();
    s += a.x() * b.y() - a.y() * b.x();
    spread += a.head<2>().squaredNorm() + b.head<2>().squaredNorm();
  }
  // Points stacked on one vertical line: every yaw fits equally well.
  if (!(spread > 0.0) || std::hypot(c, s) <= 1e-12 * spread) return false;
  *R = Eigen::AngleAxisd(std::atan2(s, c), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  *t = md - (*R) * ms;
  return true;
}

double TiltDeg(const Eigen::Isometry3d& T_ref, const Eigen::Isometry3d& T_est) {
  const Eigen::Vector3d g_ref = T_ref.linear().transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d g_est = T_est.linear().transpose() * Eigen::Vector3d::UnitZ();
  // atan2 keeps full precision at small angles, where acos of the dot product loses it.
  return std::atan2(g_ref.cross(g_est).norm(), g_ref.dot(g_est)) * 180.0 / M_PI;
}

namespace {

// Gravity metrics over already associated poses r[k] <-> e[k] (estimate not aligned).
GravityMetrics GravityOfAssociated(const Trajectory& r, const Trajectory& e, double tilt_after_s) {
  GravityMetrics g;
  if (r.empty() || r.size() != e.size()) return g;
  std::vector<double> late;
  const double t_from = r.front().stamp_s + tilt_after_s;
  for (size_t k = 0; k < r.size(); ++k) {
    const double tilt = TiltDeg(r[k].T, e[k].T);
    g.tilt_deg.push_back(tilt);
    // Small slack so that a pose stamped exactly tilt_after_s later is not lost to rounding.
    if (r[k].stamp_s >= t_from - 1e-9) late.push_back(tilt);
  }
  g.tilt = ComputeStats(late);
  // Moving the first estimate pose onto the reference one by a translation and a rotation about z
  // shifts every estimated z by the same amount and rotates nothing out of the horizontal plane,
  // so the height error is the difference of the climbs since the first pose.
  const double z_e0 = e.front().T.translation().z(), z_r0 = r.front().T.translation().z();
  for (size_t k = 0; k < r.size(); ++k) {
    const double dz = (e[k].T.translation().z() - z_e0) - (r[k].T.translation().z() - z_r0);
    g.max_abs_dz_m = std::max(g.max_abs_dz_m, std::abs(dz));
    g.final_dz_m = dz;
  }
  g.path_length_m = PathLength(r);
  g.ok = true;
  return g;
}

bool Associate(const Trajectory& ref, const Trajectory& est, const EvalOptions& o, Trajectory* r,
               Trajectory* e, size_t* matched, std::string* error) {
  const auto pairs = AssociateByStamp(ref, est, o.max_diff, o.offset);
  *matched = pairs.size();
  if (pairs.empty()) {
    if (error) *error = "no matching stamps (max_diff " + std::to_string(o.max_diff) + " s)";
    return false;
  }
  for (const auto& [i, j] : pairs) {
    r->push_back(ref[i]);
    e->push_back(est[j]);
  }
  return true;
}

// Transforms the associated estimate poses e into the reference frame (positions scaled for
// Sim(3)).
bool Align(const Trajectory& r, const EvalOptions& o, Trajectory* e, EvalResult* res) {
  if (o.align == Alignment::kNone) return true;
  std::vector<Eigen::Vector3d> src, dst;
  for (size_t k = 0; k < r.size(); ++k) {
    src.push_back((*e)[k].T.translation());
    dst.push_back(r[k].T.translation());
  }
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  double s = 1.0;
  if (o.align == Alignment::kPosYaw) {
    if (!AlignPositionYaw(src, dst, &R, &t)) {
      res->error = "alignment failed (need >= 2 matched positions with horizontal extent)";
      return false;
    }
  } else if (!Umeyama(src, dst, o.align == Alignment::kSim3, &R, &t, &s)) {
    res->error = "alignment failed (need >= 3 non-collinear matched positions)";
    return false;
  }
  res->scale = s;
  res->T_ref_est.linear() = R;
  res->T_ref_est.translation() = t;
  for (StampedPose& p : *e) {
    p.T.translation() = s * R * p.T.translation() + t;
    p.T.linear() = R * p.T.linear();
  }
  return true;
}

// Associates and aligns: fills matched ref/est poses with the estimate in the reference frame.
bool Prepare(const Trajectory& ref, const Trajectory& est, const EvalOptions& o, Trajectory* r,
             Trajectory* e, EvalResult* res) {
  return Associate(ref, est, o, r, e, &res->matched, &res->error) && Align(*r, o, e, res);
}

}  // namespace

EvalResult ComputeApe(const Trajectory& ref, const Trajectory& est, const EvalOptions& o) {
  EvalResult res;
  Trajectory r, e;
  if (!Associate(ref, est, o, &r, &e, &res.matched, &res.error)) return res;
  // Before the alignment: SE(3)/Sim(3) would rotate the estimate's world z towards the
  // reference's and hide the very tilt these metrics are for.
  res.gravity = GravityOfAssociated(r, e, o.tilt_after_s);
  if (!Align(r, o, &e, &res)) return res;
  for (size_t k = 0; k < r.size(); ++k) {
    res.errors.push_back((r[k].T.translation() - e[k].T.translation()).norm());
  }
  res.stats = ComputeStats(res.errors);
  res.ok = true;
  return res;
}

EvalResult ComputeRpe(const Trajectory& ref, const Trajectory& est, const EvalOptions& o) {
  EvalResult res;
  Trajectory r, e;
  if (!Prepare(ref, est, o, &r, &e, &res)) return res;
  std::vector<size_t> ids;
  if (o.delta_in_meters) {
    // evo: a pose becomes an anchor each time the path since the last anchor reaches delta; the
    // path is measured on the (aligned) estimate unless pairs_from_reference.
    const Trajectory& traj = o.pairs_from_reference ? r : e;
    double path = 0.0;
    for (size_t k = 0; k < traj.size(); ++k) {
      if (k > 0) path += (traj[k].T.translation() - traj[k - 1].T.translation()).norm();
      if (path >= o.delta) {
        ids.push_back(k);
        path = 0.0;
      }
    }
  } else {
    const size_t step = static_cast<size_t>(std::max(1.0, std::round(o.delta)));
    for (size_t k = 0; k < r.size(); k += step) ids.push_back(k);
  }
  for (size_t a = 0; a + 1 < ids.size(); ++a) {
    const size_t i = ids[a], j = ids[a + 1];
    const Eigen::Isometry3d Q = r[i].T.inverse() * r[j].T;
    const Eigen::Isometry3d P = e[i].T.inverse() * e[j].T;
    res.errors.push_back((Q.inverse() * P).translation().norm());
  }
  if (res.errors.empty()) {
    res.error = "no RPE pairs for delta " + std::to_string(o.delta);
    return res;
  }
  res.stats = ComputeStats(res.errors);
  res.ok = true;
  return res;
}

GravityMetrics ComputeGravityMetrics(const Trajectory& ref, const Trajectory& est,
                                     const EvalOptions& o, std::string* error) {
  Trajectory r, e;
  size_t matched = 0;
  if (!Associate(ref, est, o, &r, &e, &matched, error)) return GravityMetrics();
  return GravityOfAssociated(r, e, o.tilt_after_s);
}

double PathLength(const Trajectory& traj) {
  double len = 0.0;
  for (size_t k = 1; k < traj.size(); ++k) {
    len += (traj[k].T.translation() - traj[k - 1].T.translation()).norm();
  }
  return len;
}

std::string FormatStatsTable(const std::string& title, const std::string& subtitle,
                             const ErrorStats& stats) {
  std::ostringstream os;
  os << title << "\n";
  if (!subtitle.empty()) os << subtitle << "\n";
  os << "\n";
  const std::pair<const char*, double> rows[] = {
      {"max", stats.max},   {"mean", stats.mean}, {"median", stats.median}, {"min", stats.min},
      {"rmse", stats.rmse}, {"sse", stats.sse},   {"std", stats.std}};
  char buf[64];
  for (const auto& [name, value] : rows) {
    std::snprintf(buf, sizeof(buf), "%10s\t%.6f\n", name, value);
    os << buf;
  }
  return os.str();
}

const char* AlignmentDescription(Alignment align) {
  switch (align) {
    case Alignment::kNone:
      return "(not aligned)";
    case Alignment::kSE3:
      return "(with SE(3) Umeyama alignment)";
    case Alignment::kSim3:
      return "(with Sim(3) Umeyama alignment)";
    case Alignment::kPosYaw:
      return "(with position + yaw (4-DoF) alignment)";
  }
  return "";
}

std::string FormatGravityLines(const GravityMetrics& g, double tilt_after_s) {
  if (!g.ok) return "";
  char buf[256];
  std::string out;
  if (g.tilt.count > 0) {
    std::snprintf(buf, sizeof(buf),
                  "tilt vs. true gravity (deg, not aligned; %zu poses from %g s on): median %.4f, "
                  "max %.4f\n",
                  g.tilt.count, tilt_after_s, g.tilt.median, g.tilt.max);
  } else {
    std::snprintf(buf, sizeof(buf),
                  "tilt vs. true gravity (deg, not aligned): no pose from %g s on\n", tilt_after_s);
  }
  out += buf;
  std::snprintf(buf, sizeof(buf),
                "height error (first pose matched by translation + yaw): final %+.4f m (%+.4f %% "
                "of a %.1f m path), max |dz| %.4f m\n",
                g.final_dz_m, g.FinalDzPercent(), g.path_length_m, g.max_abs_dz_m);
  out += buf;
  return out;
}

}  // namespace ppf
