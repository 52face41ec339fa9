// Prediction without the IMU's translation: the LiDAR-only mode (imu.mode none, or auto without
// IMU data) and the moving start's window. The constant-velocity model (motion_model.hpp), or the
// gyro for the turn, predicts; the guesses around it are aligned coarsely (hypothesis_search.hpp).
#include <algorithm>
#include <cmath>
#include <deque>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "lio_ppf_impl.hpp"
#include "ppf_core/lio/deskew.hpp"
#include "ppf_core/lio/so3.hpp"

namespace ppf {

// The first scan of a LiDAR-only map: the world is its LiDAR frame. Gravity cannot be observed,
// so it is set straight down in that frame only to make T_world_map the identity.
void LioPpf::Impl::StartLidarOnly(double t) {
  state = NavState();
  state.stamp_s = t;
  const Eigen::Isometry3d T_world_imu = config.extrinsic.T_imu_lidar.inverse();
  state.R_world_imu = T_world_imu.linear();
  state.p_world_imu = T_world_imu.translation();
  state.gravity_world = Eigen::Vector3d(0.0, 0.0, -9.80665);
  state.P = StateCov::Identity() * 1e-6;
  motion.Reset();
}

// The state at t_end from the constant-velocity model; biases, velocity and gravity are not
// observed and stay fixed (their covariance tiny and uncorrelated, so updates leave them).
void LioPpf::Impl::PredictConstantVelocity(double t_end, PoseTrace* trace) {
  // Before the map's first scan there is nothing to extrapolate: StartLidarOnly's pose stands.
  const Eigen::Isometry3d T = motion.has_pose() ? ExtrapolateModel(t_end) : state.T_world_imu();
  *trace = motion.Trace();
  if (!motion.has_pose()) {
    trace->knots.front().R = T.linear();
    trace->knots.front().p = T.translation();
  }
  state.R_world_imu = T.linear();
  state.p_world_imu = T.translation();
  state.v_world = motion.velocity_world();
  state.stamp_s = t_end;
  // Raw like an IMU sample (FillState removes the bias): non-zero only in an IMU loss.
  gyro_at_scan_end = motion.angular_velocity() + state.gyro_bias;
  SetLidarOnlyPrior();
}

// The constant-velocity model's pose at t_end. Across a gap longer than the IMU bridges, after LIO
// ran (gravity known), only the turn about the vertical is extrapolated: a vehicle's or a hand's
// roll and pitch rates are oscillations that reverse within a second, so carrying them on over
// seconds tilts the guess by degrees, which the alignment of a street's walls and ground does
// not take back and the resumed filter then keeps. The path follows the heading's turn at the
// speed the filter had.
Eigen::Isometry3d LioPpf::Impl::ExtrapolateModel(double t_end) const {
  if (!Relocating() || state.gravity_world.norm() < 1.0) return motion.Predict(t_end);
  const double dt = t_end - motion.stamp();
  const Eigen::Isometry3d T_last = motion.pose();
  const Eigen::Vector3d up = -state.gravity_world.normalized();
  // Swing-twist: the part of the extrapolated turn about `up`.
  const Eigen::Quaterniond q(motion.Predict(t_end).linear() * T_last.linear().transpose());
  const Eigen::Vector3d axis_part = q.vec().dot(up) * up;
  Eigen::Quaterniond twist(q.w(), axis_part.x(), axis_part.y(), axis_part.z());
  if (twist.norm() < 1e-9) twist = Eigen::Quaterniond::Identity();
  twist.normalize();
  const Eigen::Matrix3d half_turn = SO3Exp(0.5 * SO3Log(twist.toRotationMatrix()));
  Eigen::Isometry3d T = T_last;
  T.linear() = NormalizeRotation(twist.toRotationMatrix() * T_last.linear());
  T.translation() += half_turn * motion.velocity_world() * dt;
  return T;
}

void LioPpf::Impl::SetLidarOnlyPrior() {
  const double rot =
      fallback_scan ? config.imu.loss_prior_rot_std : config.lidar_only.prior_rot_std;
  const double pos =
      fallback_scan ? config.imu.loss_prior_pos_std : config.lidar_only.prior_pos_std;
  state.P = StateCov::Identity() * 1e-6;
  state.P.block<3, 3>(kRot, kRot).diagonal().setConstant(rot * rot);
  state.P.block<3, 3>(kPos, kPos).diagonal().setConstant(pos * pos);
}

// Moving start: the gyro measures the turn however fast it is (a hand-held sensor turns at
// 150 deg/s); only the translation comes from the constant-velocity model. Gravity is not
// needed for this, nor the bias (0.1 s of a few mrad/s).
void LioPpf::Impl::PredictGyro(double t_end, PoseTrace* trace) {
  const double t0 = motion.stamp();
  const std::vector<ImuSample> samples(imu.begin(), imu.end());
  PoseTrace g;
  ImuKnot k;
  k.t = t0;
  k.R = motion.pose().linear();
  k.p = motion.pose().translation();
  k.v = motion.velocity_world();
  std::vector<double> times{t0};
  for (const ImuSample& s : samples) {
    if (s.stamp_s > t0 && s.stamp_s < t_end) times.push_back(s.stamp_s);
  }
  times.push_back(t_end);
  for (size_t i = 0; i + 1 < times.size(); ++i) {
    const double h = times[i + 1] - times[i];
    k.omega = 0.5 * (InterpolateImu(samples, times[i]).angular_velocity +
                     InterpolateImu(samples, times[i + 1]).angular_velocity);
    g.knots.push_back(k);
    k.t = times[i + 1];
    k.R = NormalizeRotation(k.R * SO3Exp(k.omega * h));
    k.p += k.v * h;
  }
  k.omega = InterpolateImu(samples, t_end).angular_velocity;
  g.knots.push_back(k);  // holds the last rate for points after t_end
  *trace = g;
  state.R_world_imu = k.R;
  state.p_world_imu = k.p;
  gyro_at_scan_end = k.omega;
  imu_prediction = true;
}

// The guesses of hypothesis_search.hpp around the model's prediction (state at t_end); the
// best aligned one becomes the prediction of the update and of the skeleton tracker.
CoarseAlignment LioPpf::Impl::AlignGuesses(double t_end) {
  const Eigen::Isometry3d& T_il = config.extrinsic.T_imu_lidar;
  const double dt = t_end - motion.stamp();
  const Eigen::Isometry3d T_last = motion.pose();
  const Eigen::Isometry3d T_cv = ExtrapolateModel(t_end);
  std::vector<MotionHypothesis> h;
  if (imu_prediction) h.push_back({"gyro", state.T_world_imu() * T_il});
  imu_prediction = false;
  h.push_back({"constant velocity", T_cv * T_il});
  h.push_back({"no motion", T_last * T_il});
  for (double scale : {0.5, 1.5}) {
    Eigen::Isometry3d d = motion.Delta(dt);
    d.linear() = SO3Exp(scale * SO3Log(d.linear()));
    std::ostringstream os;
    os << "turn x" << scale;
    h.push_back({os.str(), T_last * d * T_il});
  }
  const double a = config.lidar_only.offset_deg * M_PI / 180.0;
  auto turned = [&](const std::string& name, const Eigen::Vector3d& axis, double angle) {
    Eigen::Isometry3d R = Eigen::Isometry3d::Identity();
    R.linear() = SO3Exp(axis * angle);
    h.push_back({name, T_cv * T_il * R});
  };
  if (a > 0.0) {
    turned("turn z+", Eigen::Vector3d::UnitZ(), a);
    turned("turn z-", Eigen::Vector3d::UnitZ(), -a);
    turned("turn z++", Eigen::Vector3d::UnitZ(), 2 * a);
    turned("turn z--", Eigen::Vector3d::UnitZ(), -2 * a);
    turned("turn x+", Eigen::Vector3d::UnitX(), a);
    turned("turn x-", Eigen::Vector3d::UnitX(), -a);
    turned("turn y+", Eigen::Vector3d::UnitY(), a);
    turned("turn y-", Eigen::Vector3d::UnitY(), -a);
  }
  LidarOnlyOptions options = config.lidar_only;
  const size_t before_along = h.size();
  if (fallback_scan) AddAlongTrackGuesses(T_cv * T_il, motion.velocity_world(), dt, &h);
  if (h.size() > before_along) options.good_fit = 1.0;  // along a street many places fit well
  if (recent_fits.size() >= 3) {
    options.good_fit =
        std::min(options.good_fit, options.good_fit_relative * UpperMedian(recent_fits));
  }
  CoarseAlignment c = AlignHypotheses(frame, h, options, config.iekf, config.knn);
  recent_fits.push_back(c.fit);
  if (recent_fits.size() > 10) recent_fits.pop_front();
  const Eigen::Isometry3d T_world_imu = c.T_world_lidar * T_il.inverse();
  state.R_world_imu = T_world_imu.linear();
  state.p_world_imu = T_world_imu.translation();
  frame.T_world_lidar_predicted = c.T_world_lidar;
  SetLidarOnlyPrior();
  return c;
}

// After a long gap without IMU (an IMU loss, both streams silent) the speed along the way is
// unknown by what an unmeasured acceleration (imu.gap_acc_std, 3 sigma) makes of it over dt; the
// coarse alignment reaches about one neighbour distance from a guess, and along a street the
// parallel walls fit almost anywhere: guesses every neighbour distance along the velocity, up to
// that reach, all of them aligned (the one explaining the most points wins).
void LioPpf::Impl::AddAlongTrackGuesses(const Eigen::Isometry3d& T_world_lidar,
                                        const Eigen::Vector3d& v_world, double dt,
                                        std::vector<MotionHypothesis>* h) const {
  constexpr int kMaxPerSide = 20;
  const double spacing = std::max(config.knn.max_neighbor_distance, 0.25);
  const double reach = 0.5 * 3.0 * config.imu.gap_acc_std * dt * dt;
  if (v_world.norm() < 0.5 || reach < spacing) return;
  const Eigen::Vector3d u = v_world.normalized();
  const int n = std::min(kMaxPerSide, static_cast<int>(std::ceil(reach / spacing)));
  for (int k = 1; k <= n; ++k) {
    for (int sign : {1, -1}) {
      Eigen::Isometry3d T = T_world_lidar;
      T.translation() += sign * k * spacing * u;
      std::ostringstream os;
      os << "along " << (sign > 0 ? "+" : "-") << k * spacing << " m";
      h->push_back({os.str(), T});
    }
  }
}

namespace {

// The motion over the scan as one constant body twist from the last registered pose (T0 at t0:
// the scan's start, or earlier after dropped scans) to the pose at t1. An interpolation between
// two poses: only the change of the turn rate within the interval is missed, where the
// constant-velocity trace extrapolates the previous interval's twist and misses the whole change
// since then.
PoseTrace InterpolatedTrace(const Eigen::Isometry3d& T0, double t0, const Eigen::Isometry3d& T1,
                            double t1) {
  const double dt = std::max(t1 - t0, 1e-6);
  ImuKnot k;
  k.t = t0;
  k.R = T0.linear();
  k.p = T0.translation();
  k.omega = SO3Log(T0.linear().transpose() * T1.linear()) / dt;
  k.v = (T1.translation() - T0.translation()) / dt;
  PoseTrace trace;
  trace.knots.push_back(k);
  return trace;
}

}  // namespace

// After the coarse alignment: the points were de-skewed with the constant-velocity model's
// extrapolated twist, which a hand-held turn makes wrong by degrees across one scan (what no
// guess of the end pose can repair). De-skew again with the motion interpolated from the last
// registered pose to the aligned one, update (kNN, prior about that pose), and repeat while the
// pose still moves: the end pose and the motion inside the scan converge together.
void LioPpf::Impl::RedeskewLidarOnly(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                                     double t_end) {
  const LidarOnlyOptions& lo = config.lidar_only;
  // Not for an IMU loss's scans: re-centred on each update, the looser imu.loss_prior_* let the
  // pose slide (the core's 3 s dropout test fails with it).
  if (lo.redeskew_iterations <= 0 || !lidar_only || moving_init || !motion.has_pose()) return;
  if (!(scan.has_time_field || scan.times_estimated)) return;  // nothing was de-skewed
  IekfOptions iekf = config.iekf;
  if (t_end - map_init_stamp_s < iekf.refined_gate_after_s) iekf.refined_gate = 0.0;
  KnnResidualProvider provider(config.knn);
  bool settled = false;
  for (int i = 0;; ++i) {
    const Eigen::Isometry3d T_before = state.T_world_imu();
    const PoseTrace trace = InterpolatedTrace(motion.pose(), motion.stamp(), T_before, t_end);
    DeskewToEnd(pts, trace, t_end, config.extrinsic.T_imu_lidar, &frame.points_lidar,
                config.num_threads);
    if (i == lo.redeskew_iterations || settled) break;
    SetLidarOnlyPrior();
    provider.BeginScan(frame);
    const IekfReport rep = IekfUpdate(iekf, config.extrinsic.T_imu_lidar, {&provider}, &state);
    const Eigen::Isometry3d d = T_before.inverse() * state.T_world_imu();
    settled = rep.skipped || (SO3Log(d.linear()).norm() < lo.redeskew_min_change &&
                              d.translation().norm() < lo.redeskew_min_change);
  }
  frame.T_world_lidar_predicted = state.T_world_imu() * config.extrinsic.T_imu_lidar;
  SetLidarOnlyPrior();
}

// The turn inside a re-localized sweep: where both streams resumed together the gyro's samples
// cover the sweep, and they measure its roll and pitch rates, which the constant-velocity model
// (the rates from before the gap, about the vertical only in its extrapolation) does not know: a
// car's body pitches and rolls on its suspension, and a sweep de-skewed with the wrong rates is
// bent, which tilts the pose the map gives it. The translation is the straight line at v through
// the pose at t_end. Empty when the samples do not cover the sweep (an IMU loss's scans).
PoseTrace LioPpf::Impl::GyroTraceToEnd(const DecodedScan& scan, const Eigen::Isometry3d& T_end,
                                       const Eigen::Vector3d& v_world, double t_end) const {
  // Covered as a resumed scan is (kResumeSlackS): the nearest sample is held for the bit of the
  // sweep before the first sample back, or after the last one.
  PoseTrace trace;
  if (!imu_back || sweep_imu.empty() || imu_back_stamp_s > scan.t_begin + kResumeSlackS ||
      last_imu_stamp < t_end - kResumeSlackS) {
    return trace;
  }
  const std::vector<ImuSample>& samples = sweep_imu;
  std::vector<double> times{scan.t_begin};
  for (const ImuSample& s : samples) {
    if (s.stamp_s > scan.t_begin && s.stamp_s < t_end) times.push_back(s.stamp_s);
  }
  times.push_back(t_end);
  const size_t n = times.size();
  trace.knots.resize(n);
  ImuKnot& last = trace.knots.back();
  last.t = t_end;
  last.R = T_end.linear();
  last.omega = InterpolateImu(samples, t_end).angular_velocity - state.gyro_bias;
  // Integrated backwards from the pose at t_end, midpoint rate per segment (as PropagateImu).
  for (size_t i = n - 1; i-- > 0;) {
    ImuKnot& k = trace.knots[i];
    k.t = times[i];
    k.omega = 0.5 * (InterpolateImu(samples, times[i]).angular_velocity +
                     InterpolateImu(samples, times[i + 1]).angular_velocity) -
              state.gyro_bias;
    k.R = NormalizeRotation(trace.knots[i + 1].R * SO3Exp(-k.omega * (times[i + 1] - times[i])));
  }
  for (ImuKnot& k : trace.knots) {
    k.p = T_end.translation() + v_world * (k.t - t_end);
    k.v = v_world;
  }
  return trace;
}

// A re-localization after a gap: the scan was de-skewed with the speed the filter had before
// the gap, and a vehicle that sped up or slowed down meanwhile smears the scan by the difference
// over one sweep, which shifts and tilts the pose the map then takes. The scan alone (Gauss-Newton
// steps on the map, no prior) measures its pose and its velocity together, from how the early
// points fit against the late ones; the frame is de-skewed again with that velocity (and the
// gyro's turn, GyroTraceToEnd), and LIO resumes with it (ResumeLio) instead of the chord over
// the gap. The wide gate finds the alignment; it also keeps rows paired with the wrong surface,
// which pull the velocity back toward the one the scan was de-skewed with, so the gate then
// narrows step by step to the fit gate (coarse to fine, as in ICP): the last steps solve on the
// rows the fit counts as on their surface, and a wider last gate still keeps enough wrong pairs
// to leave the speed biased toward the one before the gap. In kPpf the sample
// also meets the skeleton's patches: the walls and the ground are not in its kNN map.
void LioPpf::Impl::EstimateScanVelocity(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                                        double t_end) {
  has_scan_velocity = false;
  if (!(scan.has_time_field || scan.times_estimated)) return;  // nothing to observe it by
  if (pts.size() != frame.points_lidar.size() || pts.empty()) return;
  constexpr int kWideSteps = 8;
  constexpr int kNarrowSteps = 12;
  const Eigen::Isometry3d& T_il = config.extrinsic.T_imu_lidar;
  // The filter's speed before the gap, along the re-localized heading.
  const Eigen::Vector3d v_body = motion.pose().linear().transpose() * motion.velocity_world();
  speed_before_gap = v_body.norm();
  ImuKnot knot;
  knot.t = t_end;
  knot.R = state.R_world_imu;
  knot.p = state.p_world_imu;
  knot.v = state.R_world_imu * v_body;
  knot.omega = motion.angular_velocity();
  PoseTrace trace;
  trace.knots.push_back(knot);
  DeskewToEnd(pts, trace, t_end, T_il, &frame.points_lidar, config.num_threads);

  std::vector<size_t> kept;
  ScanFrame sample = SampleFrame(frame, config.lidar_only.coarse_points, &kept);
  if (tracker) sample.patches = &tracker->patch_map();
  std::vector<float> dt;
  dt.reserve(kept.size());
  for (size_t i : kept) dt.push_back(static_cast<float>(pts[i].t - t_end));
  // The vertical speed stays the filter's: a sweep's vertical smear is what a pitch of the ground
  // also makes, and a vehicle's or a walker's vertical speed changes little over a gap.
  const Eigen::Vector3d up = state.gravity_world.norm() > 1.0
                                 ? Eigen::Vector3d(state.gravity_world.normalized())
                                 : Eigen::Vector3d::Zero();
  Eigen::Isometry3d T = state.T_world_imu() * T_il;
  Eigen::Vector3d v = knot.v;
  const double wide_gate = config.lidar_only.coarse_max_residual;
  const double fine_gate = std::min(wide_gate, config.lidar_only.fit_gate);
  double gate = wide_gate;
  bool narrowing = false;
  for (int k = 0, narrowed = 0; k < kWideSteps + kNarrowSteps; ++k) {
    const PoseProbe p =
        ProbePoseAndVelocity(sample, dt, up, T, config.lidar_only, config.knn, config.iekf, gate);
    T.linear() = NormalizeRotation(SO3Exp(p.step_rot) * T.linear());
    T.translation() += p.step_pos;
    v += p.step_vel;
    // The velocity's share of each sample point's de-skew, in the scan-end LiDAR frame.
    const Eigen::Vector3f shift = (T.linear().transpose() * p.step_vel).cast<float>();
    for (size_t i = 0; i < sample.points_lidar.size(); ++i) sample.points_lidar[i] += dt[i] * shift;
    const bool settled =
        p.step_rot.norm() < 1e-4 && p.step_pos.norm() < 1e-3 && p.step_vel.norm() < 1e-2;
    if (narrowing) {
      if ((gate <= fine_gate && settled) || ++narrowed >= kNarrowSteps) break;
    } else {
      narrowing = settled || k + 1 >= kWideSteps;
    }
    if (narrowing) gate = std::max(fine_gate, 0.5 * gate);
  }
  const Eigen::Isometry3d T_world_imu = T * T_il.inverse();
  state.R_world_imu = T_world_imu.linear();
  state.p_world_imu = T_world_imu.translation();
  state.v_world = v;
  knot.R = state.R_world_imu;
  knot.p = state.p_world_imu;
  knot.v = v;
  // The final de-skew takes the gyro's turn where its samples cover the sweep. The velocity
  // above is still solved on the sweep bent by the model's turn: solved on the gyro's, its
  // speed scattered more over the drives measured (docs/decisions.md, "The re-localized sweep's
  // turn from the gyro").
  PoseTrace gyro = GyroTraceToEnd(scan, T_world_imu, v, t_end);
  if (!gyro.knots.empty()) {
    trace = std::move(gyro);
  } else {
    trace.knots.front() = knot;
  }
  DeskewToEnd(pts, trace, t_end, T_il, &frame.points_lidar, config.num_threads);
  frame.T_world_lidar_predicted = T;
  SetLidarOnlyPrior();
  has_scan_velocity = true;
  scan_velocity_world = v;
}

}  // namespace ppf
