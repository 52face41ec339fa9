// IMU measurements from the trajectory's exact derivatives, plus a MEMS noise model.
//
//   gyro  = omega_body + b_g + n_g
//   accel = R_world_imu^T (a_world - g_world) + b_a + n_a,   g_world = (0, 0, -gravity)
//
// White noise is given as a density (per sqrt(Hz)) and discretized with sqrt(rate); the biases
// are random walks with density per sqrt(Hz) integrated with sqrt(dt).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "ppf_sim/trajectory.hpp"

namespace ppf::sim {

struct ImuNoise {
  double gyro_noise = 2.0e-4;        // rad/s/sqrt(Hz)   (~0.011 deg/s/sqrt(Hz))
  double accel_noise = 2.0e-3;       // m/s^2/sqrt(Hz)   (~200 ug/sqrt(Hz))
  double gyro_bias_rw = 2.0e-5;      // rad/s^2/sqrt(Hz)
  double accel_bias_rw = 3.0e-4;     // m/s^3/sqrt(Hz)
  double gyro_bias_init = 2.0e-3;    // rad/s, 1 sigma of the turn-on bias
  double accel_bias_init = 3.0e-2;   // m/s^2, 1 sigma of the turn-on bias
  static ImuNoise Zero() { return ImuNoise{0, 0, 0, 0, 0, 0}; }
};

struct ImuMeasurement {
  double t = 0.0;  // sim time, s
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();   // true bias at t
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();  // true bias at t
};

// Samples at t = i / rate for i = 0 .. floor(duration * rate).
std::vector<ImuMeasurement> SimulateImu(const Trajectory& traj, double rate, double duration,
                                        const ImuNoise& noise, uint64_t seed,
                                        double gravity = 9.81);

}  // namespace ppf::sim
