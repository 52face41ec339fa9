#include "ppf_core/imu_rate_odometry.hpp"

#include <vector>

#include "ppf_core/lio/so3.hpp"

namespace ppf {

ImuRateOdometry::ImuRateOdometry(const Options& options)
    : options_(options), acc_scale_(options.acc_scale > 0.0 ? options.acc_scale : 0.0) {}

bool ImuRateOdometry::Reset(const ScanResult& r) {
  // Without the IMU in the filter its biases and gravity were never estimated; a result without a
  // pose has nothing to start from.
  if (!r.pose_valid || r.lidar_only || r.imu_lost || r.imu_clock_offset_s != 0.0 ||
      !(r.gravity_map.norm() > 1.0)) {
    valid_ = false;
    return false;
  }
  NavState s;
  s.stamp_s = r.stamp_s;
  s.R_world_imu = r.T_world_imu.linear();
  s.p_world_imu = r.T_world_imu.translation();
  s.v_world = r.velocity_world;
  s.gyro_bias = r.gyro_bias;
  s.acc_bias = r.acc_bias;
  const Eigen::Matrix3d R_world_map = r.T_world_map.linear();
  s.gravity_world = R_world_map * r.gravity_map;
  // The result's covariance has position and velocity in the world already; the gravity
  // direction's two tangent coordinates are still the map frame's, about the map's gravity. The
  // same direction error, turned into the world, in the world gravity's tangent basis:
  StateCov J = StateCov::Identity();
  J.block<2, 2>(kGrav, kGrav) =
      S2Basis(s.gravity_world).transpose() * R_world_map * S2Basis(r.gravity_map);
  s.P = J * r.covariance * J.transpose();
  state_ = s;
  valid_ = true;
  // Samples after the scan end came while the scan was registered: the newest output continues
  // from the new posterior through them.
  if (!samples_.empty() && samples_.back().stamp_s > state_.stamp_s) {
    PropagateTo(samples_.back().stamp_s);
  }
  return valid_;
}

void ImuRateOdometry::Invalidate(bool keep_samples) {
  valid_ = false;
  if (!keep_samples) {
    samples_.clear();
    if (!(options_.acc_scale > 0.0)) acc_scale_ = 0.0;  // perhaps another IMU
  }
}

std::optional<ImuRateOdometry::State> ImuRateOdometry::AddImu(const ImuSample& sample) {
  if (!samples_.empty()) {
    const double newest = samples_.back().stamp_s;
    if (sample.stamp_s <= newest && sample.stamp_s >= newest - options_.max_gap_s) {
      ++counters_.late;  // a duplicate or a reordered sample: the state is past it
      return std::nullopt;
    }
    if (sample.stamp_s < newest || sample.stamp_s - newest > options_.max_gap_s) {
      // A new timeline (far back) or a gap: nothing measured the motion in between.
      ++counters_.breaks;
      samples_.clear();
      valid_ = false;
    }
  }
  samples_.push_back(sample);
  while (samples_.size() > 2 && samples_.front().stamp_s < sample.stamp_s - options_.buffer_s) {
    samples_.pop_front();
  }
  if (!valid_ || sample.stamp_s <= state_.stamp_s) return std::nullopt;
  if (!PropagateTo(sample.stamp_s)) return std::nullopt;
  State out;
  out.stamp_s = state_.stamp_s;
  out.T_world_imu = state_.T_world_imu();
  out.velocity_world = state_.v_world;
  out.angular_velocity = sample.angular_velocity - state_.gyro_bias;
  out.covariance = state_.P;
  return out;
}

bool ImuRateOdometry::PropagateTo(double t_end) {
  if (samples_.empty()) return false;
  if (acc_scale_ <= 0.0) DetectAccScale();
  // From the last sample at or before the state's stamp (the integration interpolates there).
  size_t first = samples_.size();
  while (first > 0 && samples_[first - 1].stamp_s > state_.stamp_s) --first;
  if (first > 0) {
    --first;
  } else if (samples_.front().stamp_s - state_.stamp_s > options_.max_gap_s) {
    // The posterior lies before every kept sample, by more than a gap.
    ++counters_.breaks;
    valid_ = false;
    return false;
  }
  const std::vector<ImuSample> segment(samples_.begin() + static_cast<std::ptrdiff_t>(first),
                                       samples_.end());
  PropagateImu(segment, t_end, acc_scale_, options_.noise, &state_, nullptr);
  return true;
}

// As the initializer decides (imu_init.cpp): a mean norm near 1 is a driver reporting in g.
void ImuRateOdometry::DetectAccScale() {
  double sum = 0.0;
  for (const ImuSample& s : samples_) sum += s.linear_acceleration.norm();
  const double mean = sum / static_cast<double>(samples_.size());
  acc_scale_ = (mean > 0.5 && mean < 1.5) ? 9.80665 : 1.0;
}

}  // namespace ppf
