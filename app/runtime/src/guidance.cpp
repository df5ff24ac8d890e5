// Guidance from an expert's recording: vh/runtime/guidance.h.
#include "vh/runtime/guidance.h"

#include "vh/runtime/even_samples.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "vh/runtime/sha256.h"

namespace vh::runtime {

namespace {

haptics::Pose recordPose(const TickRecord& r) {
  haptics::Pose X;
  X.p_AB_m = Eigen::Vector3d(r.p_WD_m[0], r.p_WD_m[1], r.p_WD_m[2]);
  X.R_AB = Eigen::Quaterniond(r.q_WD[0], r.q_WD[1], r.q_WD[2], r.q_WD[3]);
  if (X.R_AB.norm() > 0.0) X.R_AB.normalize();
  else X.R_AB = Eigen::Quaterniond::Identity();
  return X;
}

constexpr double kMergeDistance_m = 1e-6;  // records closer than this to the last vertex are merged

}  // namespace

ExpertPath::ExpertPath(const Recording& expert, std::string file_sha256, std::string file_name, std::string file_path)
    : scene_(sceneIdentity(expert.metadata_json)),
      file_sha256_(std::move(file_sha256)),
      file_name_(std::move(file_name)),
      file_path_(std::move(file_path)) {
  std::vector<haptics::GuidancePath::Segment> segments;
  bool have_last = false;
  haptics::Pose last;
  for (const TickRecord& r : expert.records) {
    if ((r.flags & kRecordFlagBadSample) != 0) {
      have_last = false;  // a gap: no segment across a sample that was not used
      continue;
    }
    const haptics::Pose X = recordPose(r);
    if (!X.p_AB_m.allFinite()) continue;
    const bool jump = (r.flags & kRecordFlagPlacement) != 0;
    if (have_last && !jump && (X.p_AB_m - last.p_AB_m).norm() < kMergeDistance_m) continue;
    if (have_last && !jump) {
      segments.push_back({last.p_AB_m, X.p_AB_m});
      segment_from_.push_back(last);
      segment_to_.push_back(X);
    }
    points_.push_back(X.p_AB_m);
    last = X;
    have_last = true;
  }
  if (points_.size() < 2 || segments.empty())
    throw std::invalid_argument("the expert's recording has no path to guide along (fewer than two usable records)");
  path_ = haptics::GuidancePath(std::move(segments));
  dtw_samples_ = devicePathSamples(expert, kDtwSamples);
  if (!expert.warnings.empty()) {  // truncated, bit-flipped, killed: say so and how much is used
    const double read_s = expert.records.back().time_s - expert.records.front().time_s;
    damage_ = "the expert's recording" + (file_name_.empty() ? std::string() : " " + file_name_) +
              " is damaged or unfinished; guidance follows the " + std::to_string(expert.records.size()) +
              " records read (" + std::to_string(static_cast<long long>(std::lround(read_s * 10.0)) / 10) + "." +
              std::to_string(static_cast<long long>(std::lround(read_s * 10.0)) % 10) + " s of the path): ";
    for (std::size_t w = 0; w < expert.warnings.size(); ++w) damage_ += (w > 0 ? "; " : "") + expert.warnings[w];
  }
}

haptics::Pose ExpertPath::poseAt(const haptics::PathPoint& p) const noexcept {
  if (p.segment < 0 || static_cast<std::size_t>(p.segment) >= segment_from_.size())
    return segment_from_.empty() ? haptics::Pose{} : segment_from_.front();
  const auto i = static_cast<std::size_t>(p.segment);
  haptics::Pose X;
  X.p_AB_m = p.p_W_m;
  X.R_AB = segment_from_[i].R_AB.slerp(p.s, segment_to_[i].R_AB);
  return X;
}

std::shared_ptr<const ExpertPath> loadExpertPath(const std::filesystem::path& file,
                                                 const std::string& session_metadata_json, RecordingFiles files) {
  const Recording expert = readRecording(file, files);
  requireSameScene(sceneIdentity(session_metadata_json), sceneIdentity(expert.metadata_json),
                   "the guide recording " + file.filename().string(), "guidance needs the same dataset");
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(file, ec).lexically_normal();
  return std::make_shared<const ExpertPath>(expert, sha256File(file), file.filename().string(),
                                            ec ? file.string() : absolute.string());
}

haptics::GuidanceGains clampGuidance(const haptics::GuidanceGains& gains, const DeviceLimits& limits) noexcept {
  haptics::GuidanceGains g = gains;
  if (!(g.stiffness_N_per_m >= 0.0) || !std::isfinite(g.stiffness_N_per_m)) g.stiffness_N_per_m = 0.0;
  if (!(g.cap_N >= 0.0) || !std::isfinite(g.cap_N)) g.cap_N = 0.0;
  g.stiffness_N_per_m = std::min(g.stiffness_N_per_m, limits.max_linear_stiffness_N_per_m);
  g.cap_N = std::min(g.cap_N, limits.max_force_N);
  return g;
}

std::string guidanceEventJson(const ExpertPath& expert, const haptics::GuidanceGains& applied,
                              const haptics::GuidanceGains& requested) {
  nlohmann::json d;
  d["expert_sha256"] = expert.fileSha256();
  d["expert_file"] = expert.fileName();
  if (!expert.filePath().empty()) d["expert_path"] = expert.filePath();
  d["stiffness_N_per_m"] = applied.effectiveStiffness_N_per_m();
  d["requested_stiffness_N_per_m"] = requested.stiffness_N_per_m;
  d["cap_N"] = applied.cap_N;
  d["deadband_m"] = applied.deadband_m;
  d["fade"] = applied.fade;
  d["repetition"] = applied.repetition;
  return d.dump();
}

CompliantHand::CompliantHand(Device& intended, const HandImpedance& hand, double step_s)
    : intended_(intended), hand_(hand), step_s_(step_s) {
  if (!(hand.mass_kg > 0.0) || !(hand.stiffness_N_per_m > 0.0) || !(hand.damping_N_s_per_m >= 0.0) ||
      !std::isfinite(hand.mass_kg + hand.stiffness_N_per_m + hand.damping_N_s_per_m))
    throw std::invalid_argument("the hand model needs a mass > 0 kg, a stiffness > 0 N/m and a damping >= 0 N s/m");
  if (!(step_s > 0.0) || !std::isfinite(step_s)) throw std::invalid_argument("the hand model needs a step > 0 s");
  // Semi-implicit Euler on m x'' = -k x - b x' is stable only while k dt^2 / m + 2 b dt / m < 4
  // (Jury's test on its characteristic polynomial); beyond it the hand's pose grows without
  // bound and every sample after a few is bad.
  const double stability = (hand.stiffness_N_per_m * step_s * step_s + 2.0 * hand.damping_N_s_per_m * step_s) / hand.mass_kg;
  if (!(stability < 4.0)) {
    const double k_max = (4.0 * hand.mass_kg - 2.0 * hand.damping_N_s_per_m * step_s) / (step_s * step_s);
    char text[300];
    std::snprintf(text, sizeof text,
                  "the hand model at %g N/m is unstable at %g Hz (mass %g kg, damping %g N s/m): its stiffness must be "
                  "below %.4g N/m",
                  hand.stiffness_N_per_m, 1.0 / step_s, hand.mass_kg, hand.damping_N_s_per_m, k_max);
    throw std::invalid_argument(text);
  }
}

bool CompliantHand::read(DeviceSample& sample) noexcept {
  if (!intended_.read(sample)) return false;
  if (!sample.valid || !sample.X_WD.p_AB_m.allFinite()) return true;
  const Eigen::Vector3d x_int = sample.X_WD.p_AB_m, v_int = sample.v_WD_m_per_s;
  if (!started_) {
    p_W_m_ = x_int;
    v_W_m_per_s_ = v_int;
    started_ = true;
  } else {
    const Eigen::Vector3d a = (hand_.stiffness_N_per_m * (x_int - p_W_m_) +
                               hand_.damping_N_s_per_m * (v_int - v_W_m_per_s_) + force_W_N_) /
                              hand_.mass_kg;
    v_W_m_per_s_ += step_s_ * a;  // semi-implicit Euler: the new velocity moves the position
    p_W_m_ += step_s_ * v_W_m_per_s_;
  }
  sample.X_WD.p_AB_m = p_W_m_;
  sample.v_WD_m_per_s = v_W_m_per_s_;
  return true;
}

void CompliantHand::command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  force_W_N_ = force_W_N.allFinite() ? force_W_N : Eigen::Vector3d::Zero();
  intended_.command(force_W_N, torque_W_Nm);
}

GuidanceTrack::GuidanceTrack(std::shared_ptr<const ExpertPath> expert, const haptics::GuidanceGains& applied)
    : expert_(std::move(expert)), gains_(applied) {
  if (!expert_) throw std::invalid_argument("guidance needs an expert's path");
}

Eigen::Vector3d GuidanceTrack::step(std::uint64_t i, double servo_rate_Hz, const Eigen::Vector3d& p_WD_m,
                                    bool sample_ok, RecordingWriter* recorder) {
  haptics::GuidanceForce g;
  if (sample_ok) {
    g = haptics::guidanceForce(expert_->path(), gains_, p_WD_m);
    device_path_.push_back(p_WD_m);
    distance_sum_m_ += g.nearest.distance_m;
    ++ticks_;
  }
  const double magnitude = g.force_W_N.norm();
  max_force_N_ = std::max(max_force_N_, magnitude);
  window_peak_N_ = std::max(window_peak_N_, magnitude);
  if (recorder != nullptr && (i + 1) % kGuidanceEventTicks == 0) {
    RecordingEvent event;
    event.time_s = static_cast<double>(i) / servo_rate_Hz;
    event.tick = i + 1;
    event.type = "guidance_force";
    event.detail_json = nlohmann::json{{"F_W_N", {g.force_W_N.x(), g.force_W_N.y(), g.force_W_N.z()}},
                                       {"peak_N", window_peak_N_},
                                       {"distance_m", sample_ok ? g.nearest.distance_m : -1.0}}
                            .dump();
    recorder->addEvent(event);
    window_peak_N_ = 0.0;
  }
  return g.force_W_N;
}

namespace {

std::vector<Eigen::Vector3d> thinned(const std::vector<Eigen::Vector3d>& p, std::size_t count) {
  if (p.size() <= count || count < 2) return p;
  std::vector<Eigen::Vector3d> out;
  out.reserve(count);
  for (std::size_t j = 0; j < count; ++j) out.push_back(p[evenlySpacedIndex(j, p.size(), count)]);
  return out;
}

}  // namespace

double GuidanceTrack::dtwMean_m() const {
  if (device_path_.empty()) return 0.0;
  return dynamicTimeWarping(thinned(device_path_, ExpertPath::kDtwSamples), expert_->dtwSamples()).mean_distance_m;
}

GuidanceReport GuidanceTrack::report(bool compliant_hand) const {
  GuidanceReport r;
  r.expert_sha256 = expert_->fileSha256();
  r.expert_damage = expert_->damage();
  r.stiffness_N_per_m = gains_.effectiveStiffness_N_per_m();
  r.cap_N = gains_.cap_N;
  r.repetition = gains_.repetition;
  r.max_force_N = max_force_N_;
  r.mean_distance_m = meanDistance_m();
  r.dtw_mean_m = dtwMean_m();
  r.compliant_hand = compliant_hand;
  return r;
}

std::string GuidanceReport::toJson() const {
  nlohmann::ordered_json j;
  j["expert_sha256"] = expert_sha256;
  j["stiffness_N_per_m"] = stiffness_N_per_m;
  j["cap_N"] = cap_N;
  j["repetition"] = repetition;
  j["max_force_N"] = max_force_N;
  j["mean_distance_m"] = mean_distance_m;
  j["dtw_mean_m"] = dtw_mean_m;
  j["compliant_hand"] = compliant_hand;
  if (!expert_damage.empty()) j["expert_damage"] = expert_damage;
  return j.dump();
}

std::string GuidanceReport::summary() const {
  char line[320];
  std::snprintf(line, sizeof line,
                "guidance K %.4g N/m (repetition %d), cap %.3g N, max %.3g N; mean distance to the expert %.3f mm, "
                "DTW %.3f mm%s",
                stiffness_N_per_m, repetition, cap_N, max_force_N, mean_distance_m * 1e3, dtw_mean_m * 1e3,
                compliant_hand ? "" : " (rigid device: nothing to guide)");
  return line;
}

double meanDistanceToPath(const std::vector<Eigen::Vector3d>& path, const haptics::GuidancePath& expert) {
  if (path.empty() || expert.empty()) return 0.0;
  double sum = 0.0;
  for (const Eigen::Vector3d& p : path) sum += expert.nearest(p).distance_m;
  return sum / static_cast<double>(path.size());
}

}  // namespace vh::runtime
