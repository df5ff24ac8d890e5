#pragma once
/// @file
/// The drivers' velocity estimate (DeviceSample::v_WD_m_per_s): the finite difference of
/// successive positions, low-passed by a first-order filter with cut-off f_c,
///   v_n = v_{n-1} + alpha (dp / dt - v_{n-1}),  alpha = 1 - exp(-2 pi f_c dt),
/// so that an uneven sample interval dt (USB, scheduler jitter) keeps the cut-off in Hz.
/// Units: positions [m] in the device's base frame, times [s], velocities [m/s].
/// Threads: one instance per thread (no synchronisation); never allocates or throws.
#include <cmath>
#include <numbers>

#include <Eigen/Core>

namespace vh::devices {

class VelocityFilter {
 public:
  /// @param cutoff_Hz the filter's cut-off [Hz] (> 0).
  explicit VelocityFilter(double cutoff_Hz) noexcept : cutoff_Hz_(cutoff_Hz) {}

  /// Takes the position p [m] sampled at t [s]; the velocity changes only when a previous
  /// sample exists and t is later than it (a repeated or older time stamp only replaces the
  /// previous sample). @return the filtered velocity [m/s].
  const Eigen::Vector3d& update(const Eigen::Vector3d& p_m, double t_s) noexcept {
    if (have_previous_ && t_s > t_previous_s_) {
      const double dt = t_s - t_previous_s_;
      const double alpha = 1.0 - std::exp(-2.0 * std::numbers::pi * cutoff_Hz_ * dt);
      v_m_per_s_ += alpha * ((p_m - p_previous_m_) / dt - v_m_per_s_);
    }
    p_previous_m_ = p_m;
    t_previous_s_ = t_s;
    have_previous_ = true;
    return v_m_per_s_;
  }
  /// The filtered velocity [m/s] (zero before the second sample).
  const Eigen::Vector3d& velocity() const noexcept { return v_m_per_s_; }
  /// Forgets the previous sample and the velocity (a new connection).
  void reset() noexcept { *this = VelocityFilter(cutoff_Hz_); }

 private:
  double cutoff_Hz_;
  Eigen::Vector3d p_previous_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_m_per_s_ = Eigen::Vector3d::Zero();
  double t_previous_s_ = 0.0;
  bool have_previous_ = false;
};

}  // namespace vh::devices
