#include "ppf_sim/imu_simulator.hpp"

#include <cmath>
#include <stdexcept>

#include "ppf_sim/rng.hpp"

namespace ppf::sim {

std::vector<ImuMeasurement> SimulateImu(const Trajectory& traj, double rate, double duration,
                                        const ImuNoise& noise, uint64_t seed, double gravity) {
  if (!(rate > 0.0)) throw std::invalid_argument("imu rate must be > 0");
  Rng rng(seed, 0x1A1Au);
  auto normal3 = [&rng]() { return Eigen::Vector3d(rng.Normal(), rng.Normal(), rng.Normal()); };
  const double dt = 1.0 / rate;
  const Eigen::Vector3d g(0.0, 0.0, -gravity);
  Eigen::Vector3d bg = noise.gyro_bias_init * normal3();
  Eigen::Vector3d ba = noise.accel_bias_init * normal3();
  const int n = static_cast<int>(std::floor(duration * rate + 1e-9)) + 1;
  std::vector<ImuMeasurement> out;
  out.reserve(n);
  for (int i = 0; i < n; ++i) {
    const double t = i * dt;
    if (i > 0) {
      bg += noise.gyro_bias_rw * std::sqrt(dt) * normal3();
      ba += noise.accel_bias_rw * std::sqrt(dt) * normal3();
    }
    const TrajectoryState s = traj.Evaluate(t);
    ImuMeasurement m;
    m.t = t;
    m.gyro_bias = bg;
    m.accel_bias = ba;
    m.gyro = s.omega + bg + noise.gyro_noise * std::sqrt(rate) * normal3();
    m.accel = s.R.transpose() * (s.a - g) + ba + noise.accel_noise * std::sqrt(rate) * normal3();
    out.push_back(m);
  }
  return out;
}

}  // namespace ppf::sim
