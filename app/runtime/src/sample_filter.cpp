// The device-sample plausibility test of vh/runtime/sample_filter.h.
#include "vh/runtime/sample_filter.h"

#include <cmath>

namespace vh::runtime {

bool SampleFilter::reachable(const haptics::Pose& from, const haptics::Pose& X, double elapsed_s) const noexcept {
  const double distance_m = (X.p_AB_m - from.p_AB_m).norm();
  // A NaN or infinite limit means no limit (std::isfinite false): only a finite one rejects.
  const double v = limits_.max_speed_m_per_s;
  if (std::isfinite(v) && distance_m > v * elapsed_s + kPositionSlack_m) return false;
  const double w = limits_.max_angular_speed_rad_per_s;
  if (std::isfinite(w) && from.R_AB.angularDistance(X.R_AB) > w * elapsed_s + kAngleSlack_rad) return false;
  return true;
}

SampleFilter::Verdict SampleFilter::check(const DeviceSample& sample, bool read_ok, double dt_s) noexcept {
  const double dt = std::isfinite(dt_s) && dt_s > 0.0 ? dt_s : 0.0;
  since_good_s_ += dt;
  since_candidate_s_ += dt;
  if (!read_ok || !sample.valid) return Verdict::kMissing;
  if (!have_connection_ || sample.connection != connection_) {  // a new connection: start afresh
    connection_ = sample.connection;
    have_connection_ = true;
    have_good_ = false;
    candidate_run_ = 0;
  }
  const haptics::Pose& X = sample.X_WD;
  if (!X.allFinite() || std::abs(X.R_AB.norm() - 1.0) > 1e-3) {
    ++stats_.implausible;
    ++stats_.nonfinite;
    return Verdict::kImplausible;
  }
  const double r = limits_.workspace_radius_m;
  if (std::isfinite(r) && (X.p_AB_m - limits_.workspace_centre_m).norm() > kWorkspaceFactor * r + kPositionSlack_m) {
    ++stats_.implausible;
    ++stats_.outside;
    return Verdict::kImplausible;
  }
  if (!have_good_ || reachable(good_, X, since_good_s_)) {
    good_ = X;
    since_good_s_ = 0.0;
    have_good_ = true;
    candidate_run_ = 0;
    return Verdict::kGood;
  }
  // Too fast for the last good sample. Part of a consistent run away from it?
  if (candidate_run_ > 0 && reachable(candidate_, X, since_candidate_s_)) {
    ++candidate_run_;
  } else {
    candidate_run_ = 1;
  }
  candidate_ = X;
  since_candidate_s_ = 0.0;
  if (candidate_run_ >= kReseedSamples) {
    good_ = X;
    since_good_s_ = 0.0;
    candidate_run_ = 0;
    ++stats_.reseeds;
    return Verdict::kReseeded;
  }
  ++stats_.implausible;
  ++stats_.too_fast;
  return Verdict::kImplausible;
}

}  // namespace vh::runtime
