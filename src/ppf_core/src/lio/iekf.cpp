#include "ppf_core/lio/iekf.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "ppf_core/lio/so3.hpp"

namespace ppf {
namespace {

using StateVec = Eigen::Matrix<double, kStateDim, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// x (-) prior in the error-state coordinates of imu_propagation.hpp.
StateVec BoxMinus(const NavState& x, const NavState& prior) {
  StateVec d;
  d.segment<3>(kRot) = SO3Log(prior.R_world_imu.transpose() * x.R_world_imu);
  d.segment<3>(kPos) = x.p_world_imu - prior.p_world_imu;
  d.segment<3>(kVel) = x.v_world - prior.v_world;
  d.segment<3>(kBg) = x.gyro_bias - prior.gyro_bias;
  d.segment<3>(kBa) = x.acc_bias - prior.acc_bias;
  d.segment<2>(kGrav) = S2BoxMinus(x.gravity_world, prior.gravity_world);
  return d;
}

void BoxPlus(const StateVec& d, NavState* x) {
  x->R_world_imu = NormalizeRotation(x->R_world_imu * SO3Exp(d.segment<3>(kRot)));
  x->p_world_imu += d.segment<3>(kPos);
  x->v_world += d.segment<3>(kVel);
  x->gyro_bias += d.segment<3>(kBg);
  x->acc_bias += d.segment<3>(kBa);
  x->gravity_world = S2BoxPlus(x->gravity_world, d.segment<2>(kGrav));
}

// Projector onto the well-constrained eigen-directions of a 3x3 information block.
Eigen::Matrix3d StrongProjector(const Eigen::Matrix3d& info, double min_eig, const char* what,
                                Eigen::Vector3d* eig, std::string* reason) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(info);
  *eig = es.eigenvalues();
  Eigen::Matrix3d proj = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d v = es.eigenvectors().col(i);
    if (es.eigenvalues()(i) >= min_eig) {
      proj += v * v.transpose();
    } else {
      char buf[160];
      std::snprintf(buf, sizeof(buf), "%s%s along (%.2f %.2f %.2f): eig %.1f < %.1f",
                    reason->empty() ? "" : "; ", what, v.x(), v.y(), v.z(), es.eigenvalues()(i),
                    min_eig);
      *reason += buf;
    }
  }
  return proj;
}

// Drops rows whose residual exceeds the refined gate, widened to 3 robust sigmas of this
// iteration's residuals when the whole scan sits farther out (an estimate still far off): a fixed
// narrow gate would then keep only the rows that agree with the wrong estimate.
void RefineGate(double refined_gate, const Eigen::Isometry3d& T_world_lidar,
                std::vector<PointPlaneRow>* rows, std::vector<size_t>* ends) {
  std::vector<double> res(rows->size());
  for (size_t k = 0; k < rows->size(); ++k) {
    const PointPlaneRow& row = (*rows)[k];
    res[k] = std::abs(row.normal_world.dot(T_world_lidar * row.point_lidar) + row.offset);
  }
  if (res.empty()) return;
  std::vector<double> sorted = res;
  const auto mid = sorted.begin() + static_cast<long>(sorted.size() / 2);
  std::nth_element(sorted.begin(), mid, sorted.end());
  const double gate = std::max(refined_gate, 3.0 * 1.4826 * *mid);
  size_t kept = 0, begin = 0;
  for (size_t& end : *ends) {
    for (size_t k = begin; k < end; ++k) {
      if (res[k] < gate) (*rows)[kept++] = (*rows)[k];
    }
    begin = end;
    end = kept;
  }
  rows->resize(kept);
}

// The rows of one iteration from every provider (or the last iteration's, re-gated), with each
// provider's count in the report. `ends[i]`: one past provider i's last row.
void GatherRows(const IekfOptions& options, int iter, bool reuse_rows,
                const Eigen::Isometry3d& T_world_lidar,
                const std::vector<ResidualProvider*>& providers, std::vector<PointPlaneRow>* rows,
                std::vector<size_t>* ends, IekfReport* report) {
  report->rows_per_provider.assign(providers.size(), 0);
  if (!reuse_rows) {
    rows->clear();
    // Every provider's per-point loop in one team (ResidualProvider::PrepareRows): a team when
    // any of them would open one for itself, with the most threads any of them is configured for.
    std::vector<ResidualProvider::TeamWork> work(providers.size());
    bool team = false;
    int threads = 1;
    for (size_t i = 0; i < providers.size(); ++i) {
      work[i] = providers[i]->PrepareRows(T_world_lidar);
      team = team || work[i].points > work[i].team_above;
      if (work[i].points > 0) threads = std::max(threads, work[i].threads);
    }
    if (team) {
#pragma omp parallel num_threads(threads)
      for (size_t i = 0; i < providers.size(); ++i) {
        if (work[i].points > 0) providers[i]->RowsInTeam();
      }
    } else {
      for (size_t i = 0; i < providers.size(); ++i) {
        if (work[i].points > 0) providers[i]->RowsInTeam();
      }
    }
    for (size_t i = 0; i < providers.size(); ++i) {
      providers[i]->FinishRows(T_world_lidar, rows);
      (*ends)[i] = rows->size();
    }
  }
  if (iter > 0 && options.refined_gate > 0.0) {
    RefineGate(options.refined_gate, T_world_lidar, rows, ends);
  }
  for (size_t i = 0; i < providers.size(); ++i) {
    report->rows_per_provider[i] = static_cast<int>((*ends)[i] - (i == 0 ? 0 : (*ends)[i - 1]));
  }
  report->num_rows = static_cast<int>(rows->size());
}

// The rows' normal equations in the pose block. J = d r / d [dtheta, dp]. The geometry (row
// weights only) is judged per block, rotation and translation (MeasurementInformation): only
// those two diagonal blocks of its J^T J are summed, the coupling between them never read. The
// update uses the rows' range-dependent noise too (JtJ_noise, Jtr), so a far row counts less but
// still pins a direction nothing else observes.
struct NormalEquations {
  Eigen::Matrix3d JtJ_rot = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d JtJ_trans = Eigen::Matrix3d::Zero();
  Mat6 JtJ_noise = Mat6::Zero();
  Vec6 Jtr = Vec6::Zero();
};

// Adds w j j^T to the lower triangle of M; the upper one is filled once, at the end (FillUpper).
template <int N>
inline void AddLower(double w, const Eigen::Matrix<double, N, 1>& j,
                     Eigen::Matrix<double, N, N>* M) {
  for (int c = 0; c < N; ++c) {
    const double wj = w * j(c);
    for (int r = c; r < N; ++r) (*M)(r, c) += wj * j(r);
  }
}

template <int N>
inline void FillUpper(Eigen::Matrix<double, N, N>* M) {
  for (int c = 1; c < N; ++c) {
    for (int r = 0; r < c; ++r) (*M)(r, c) = (*M)(c, r);
  }
}

// Weighted moments of a group's points (IMU frame) about its first point q0: s0 = sum w,
// s1 = sum w d, s2 = sum w d d^T with d = q - q0 (about q0, so the residual sums do not cancel
// terms of the size of the range).
struct Moments {
  double s0 = 0.0;
  Eigen::Vector3d s1 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
  void Add(double w, const Eigen::Vector3d& d) {
    s0 += w;
    s1 += w * d;
    s2.noalias() += (w * d) * d.transpose();
  }
};

// Rows that share one plane (n, offset) -- the skeleton points matched to one patch come in
// runs -- enter through their moments, exactly: with m = R^T n, a row's J = [q x m; n] and
// r = r0 + m . d (r0 the residual at q0), so sum w J J^T and sum w J r are linear in s0, s1, s2.
void AddGroup(const Eigen::Vector3d& q0, const Eigen::Vector3d& n, const Eigen::Vector3d& m,
              double r0, const Moments& w, const Moments& w_noise, NormalEquations* ne) {
  // q x m = K^T q with K the cross-product matrix of m.
  Eigen::Matrix3d K;
  K << 0.0, -m.z(), m.y(), m.z(), 0.0, -m.x(), -m.y(), m.x(), 0.0;
  const auto rot_info = [&](const Moments& g) {
    const Eigen::Matrix3d q2 = g.s0 * q0 * q0.transpose() + q0 * g.s1.transpose() +
                               g.s1 * q0.transpose() + g.s2;  // sum w q q^T
    return Eigen::Matrix3d(K.transpose() * q2 * K);
  };
  ne->JtJ_rot += rot_info(w);
  ne->JtJ_trans += w.s0 * n * n.transpose();
  const Eigen::Vector3d q1 = w_noise.s0 * q0 + w_noise.s1;  // sum w q
  ne->JtJ_noise.topLeftCorner<3, 3>() += rot_info(w_noise);
  ne->JtJ_noise.bottomLeftCorner<3, 3>() += n * (K.transpose() * q1).transpose();
  ne->JtJ_noise.bottomRightCorner<3, 3>() += w_noise.s0 * n * n.transpose();
  ne->Jtr.head<3>() += K.transpose() * (r0 * q1 + q0 * w_noise.s1.dot(m) + w_noise.s2 * m);
  ne->Jtr.tail<3>() += (r0 * w_noise.s0 + m.dot(w_noise.s1)) * n;
}

NormalEquations BuildNormalEquations(const IekfOptions& options,
                                     const Eigen::Isometry3d& T_imu_lidar, const NavState& x,
                                     const std::vector<PointPlaneRow>& rows) {
  // Serial: a few thousand 6-vectors cost less than waking a thread team.
  const size_t n = rows.size();
  const Eigen::Matrix3d R = x.R_world_imu;
  const Eigen::Vector3d p = x.p_world_imu;
  NormalEquations ne;
  const double ang_var = options.laser_angular_std * options.laser_angular_std;
  const double lin_var = options.laser_point_std * options.laser_point_std;
  const auto noise_weight = [&](const PointPlaneRow& row) {
    return row.weight * lin_var / (lin_var + ang_var * row.point_lidar.squaredNorm());
  };
  const auto same_plane = [&](const PointPlaneRow& a, const PointPlaneRow& b) {
    return a.offset == b.offset && a.normal_world == b.normal_world;
  };
  // Below this many rows a plane's moments cost more than its rows.
  constexpr size_t kMinGroup = 4;
  size_t i = 0;
  while (i < n) {
    const PointPlaneRow& first = rows[i];
    size_t end = i + 1;
    while (end < n && same_plane(first, rows[end])) ++end;
    const Eigen::Vector3d m = R.transpose() * first.normal_world;
    if (end - i >= kMinGroup) {
      const Eigen::Vector3d q0 = T_imu_lidar * first.point_lidar;
      Moments w, w_noise;
      for (size_t k = i; k < end; ++k) {
        const Eigen::Vector3d d = T_imu_lidar * rows[k].point_lidar - q0;
        w.Add(rows[k].weight, d);
        w_noise.Add(noise_weight(rows[k]), d);
      }
      const double r0 = first.normal_world.dot(R * q0 + p) + first.offset;
      AddGroup(q0, first.normal_world, m, r0, w, w_noise, &ne);
    } else {
      for (size_t k = i; k < end; ++k) {
        const PointPlaneRow& row = rows[k];
        const Eigen::Vector3d q = T_imu_lidar * row.point_lidar;
        const double r = row.normal_world.dot(R * q + p) + row.offset;
        Vec6 j;
        j.head<3>() = q.cross(m);
        j.tail<3>() = row.normal_world;
        AddLower<3>(row.weight, j.head<3>(), &ne.JtJ_rot);
        AddLower<3>(row.weight, j.tail<3>(), &ne.JtJ_trans);
        const double w = noise_weight(row);
        AddLower<6>(w, j, &ne.JtJ_noise);
        ne.Jtr.noalias() += (w * r) * j;
      }
    }
    i = end;
  }
  FillUpper<6>(&ne.JtJ_noise);
  FillUpper<3>(&ne.JtJ_rot);
  FillUpper<3>(&ne.JtJ_trans);
  return ne;
}

// The measurement's information H and vector b, with the directions the geometry leaves weak
// removed when there are any (the report says which): measurements say nothing trustworthy
// there, so the IMU prediction (and its covariance) stays in charge.
void MeasurementInformation(const IekfOptions& options, const NormalEquations& ne, Mat6* H,
                            Vec6* b, IekfReport* report) {
  report->degenerate_reason.clear();
  Mat6 proj = Mat6::Zero();
  proj.topLeftCorner<3, 3>() =
      StrongProjector(ne.JtJ_rot, options.degeneracy_min_eig_rotation, "rotation",
                      &report->eig_rotation, &report->degenerate_reason);
  proj.bottomRightCorner<3, 3>() =
      StrongProjector(ne.JtJ_trans, options.degeneracy_min_eig_translation, "translation",
                      &report->eig_translation, &report->degenerate_reason);
  report->degenerate = !report->degenerate_reason.empty();
  const double inv_var = 1.0 / (options.laser_point_std * options.laser_point_std);
  *H = inv_var * ne.JtJ_noise;
  *b = inv_var * ne.Jtr;
  if (report->degenerate) {
    *H = proj * *H * proj;
    *b = proj * *b;
  }
}

}  // namespace

IekfReport IekfUpdate(const IekfOptions& options, const Eigen::Isometry3d& T_imu_lidar,
                      const std::vector<ResidualProvider*>& providers, NavState* state) {
  IekfReport report;
  const NavState prior = *state;
  NavState x = prior;
  const Eigen::LDLT<StateCov> prior_ldlt(prior.P);
  const StateCov P_inv = prior_ldlt.solve(StateCov::Identity());
  std::vector<PointPlaneRow> rows;
  StateCov A = P_inv;
  bool have_A = false;
  const int max_iter = std::max(1, options.max_iterations);

  std::vector<size_t> ends(providers.size());
  bool reuse_rows = false;  // the first iteration converged: re-gate its matches, no new search
  for (int iter = 0; iter < max_iter; ++iter) {
    auto t0 = std::chrono::steady_clock::now();
    const Eigen::Isometry3d T_world_lidar = x.T_world_imu() * T_imu_lidar;
    GatherRows(options, iter, reuse_rows, T_world_lidar, providers, &rows, &ends, &report);
    report.residuals_ms += MsSince(t0);
    t0 = std::chrono::steady_clock::now();
    if (report.num_rows < options.min_rows) {
      report.skipped = true;
      report.update_ms += MsSince(t0);
      break;
    }
    // Degeneracy from each iteration's geometry (later ones see nearly the same matches).
    Mat6 H;
    Vec6 b;
    MeasurementInformation(options, BuildNormalEquations(options, T_imu_lidar, x, rows), &H, &b,
                           &report);

    const StateVec d_prior = BoxMinus(x, prior);
    A = P_inv;
    A.topLeftCorner<6, 6>() += H;
    StateVec rhs = -P_inv * d_prior;
    rhs.head<6>() -= b;
    const StateVec dx = A.ldlt().solve(rhs);
    have_A = true;
    if (!dx.allFinite()) {
      report.skipped = true;
      x = prior;
      have_A = false;
      report.update_ms += MsSince(t0);
      break;
    }
    BoxPlus(dx, &x);
    report.iterations = iter + 1;
    report.update_ms += MsSince(t0);
    // With a refined gate the first iteration's rows only bring the estimate near: the posterior
    // is built from gated rows.
    const bool gated = options.refined_gate <= 0.0 || iter > 0;
    if (dx.segment<3>(kRot).norm() < options.convergence_rot_rad &&
        dx.segment<3>(kPos).norm() < options.convergence_trans_m) {
      if (gated) {
        report.converged = true;
        break;
      }
      // The matches are right already; only the posterior must leave out the far residuals.
      reuse_rows = true;
    } else {
      reuse_rows = false;
    }
  }

  if (have_A) {
    StateCov P = A.ldlt().solve(StateCov::Identity());
    x.P = 0.5 * (P + P.transpose());
    *state = x;
  } else {
    *state = prior;
  }
  return report;
}

}  // namespace ppf
