#include "vh/runtime/trajectory.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "vh/runtime/placement.h"

namespace vh::runtime {

using haptics::Pose;

namespace {

constexpr std::array<std::string_view, 9> kColumns{"t_s", "x_m", "y_m", "z_m", "qw", "qx", "qy", "qz", "isovalue"};
constexpr std::size_t kPoseColumns = 8;  // the isovalue column is optional

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

std::vector<std::string_view> splitComma(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t begin = 0;
  while (true) {
    const std::size_t comma = line.find(',', begin);
    fields.push_back(trim(line.substr(begin, comma == std::string_view::npos ? std::string_view::npos
                                                                              : comma - begin)));
    if (comma == std::string_view::npos) break;
    begin = comma + 1;
  }
  return fields;
}

bool parseDouble(std::string_view text, double& value) {
  if (text.empty()) return false;
  if (text.front() == '+') text.remove_prefix(1);
  const auto result = std::from_chars(text.data(), text.data() + text.size(), value);
  return result.ec == std::errc() && result.ptr == text.data() + text.size();
}

std::string lowercase(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

std::string columnList(std::size_t n = kPoseColumns) {
  std::string out;
  for (std::size_t i = 0; i < n; ++i) {
    if (i) out += ',';
    out += kColumns[i];
  }
  return out;
}

}  // namespace

Trajectory::Trajectory(std::vector<TrajectorySample> samples) : samples_(std::move(samples)) {
  if (samples_.empty()) throw std::invalid_argument("trajectory: no samples");
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    TrajectorySample& s = samples_[i];
    if (!std::isfinite(s.t_s) || !s.X_WD.allFinite() || std::isinf(s.isovalue)) {
      throw std::invalid_argument("trajectory: sample " + std::to_string(i) + " is not finite");
    }
    const double norm = s.X_WD.R_AB.norm();
    if (!(norm > 1e-12)) {
      throw std::invalid_argument("trajectory: sample " + std::to_string(i) + " has a zero quaternion");
    }
    s.X_WD.R_AB.coeffs() /= norm;
    if (i > 0 && !(s.t_s > samples_[i - 1].t_s)) {
      throw std::invalid_argument("trajectory: sample " + std::to_string(i) + " time " +
                                  std::to_string(s.t_s) + " s does not increase");
    }
  }
}

Pose Trajectory::interpolate(std::size_t segment, double t_s) const noexcept {
  const TrajectorySample& a = samples_[segment];
  const TrajectorySample& b = samples_[segment + 1];
  const double alpha = std::clamp((t_s - a.t_s) / (b.t_s - a.t_s), 0.0, 1.0);
  Pose X;
  X.p_AB_m = a.X_WD.p_AB_m + alpha * (b.X_WD.p_AB_m - a.X_WD.p_AB_m);
  X.R_AB = a.X_WD.R_AB.slerp(alpha, b.X_WD.R_AB).normalized();  // shortest arc
  return X;
}

Pose Trajectory::poseAt(double t_s) const noexcept {
  if (samples_.empty()) return Pose{};
  if (!(t_s > samples_.front().t_s)) return samples_.front().X_WD;  // also NaN
  if (t_s >= samples_.back().t_s) return samples_.back().X_WD;
  // First sample with time > t; the segment starts one before it.
  const auto it = std::upper_bound(samples_.begin(), samples_.end(), t_s,
                                   [](double t, const TrajectorySample& s) { return t < s.t_s; });
  return interpolate(static_cast<std::size_t>(it - samples_.begin()) - 1, t_s);
}

Pose Trajectory::poseAt(double t_s, std::size_t& cursor) const noexcept {
  if (samples_.empty()) return Pose{};
  if (!(t_s > samples_.front().t_s)) {
    cursor = 0;
    return samples_.front().X_WD;
  }
  if (t_s >= samples_.back().t_s) {
    cursor = samples_.size() - 1;
    return samples_.back().X_WD;
  }
  std::size_t i = std::min(cursor, samples_.size() - 2);
  if (samples_[i].t_s > t_s) i = 0;  // went backwards: restart
  while (i + 1 < samples_.size() - 1 && samples_[i + 1].t_s <= t_s) ++i;
  cursor = i;
  return interpolate(i, t_s);
}

bool Trajectory::hasIsovalues() const noexcept {
  return std::any_of(samples_.begin(), samples_.end(), [](const TrajectorySample& s) { return !std::isnan(s.isovalue); });
}

double Trajectory::isovalueAt(double t_s, double fallback) const noexcept {
  if (samples_.empty()) return fallback;
  const auto at = [fallback](const TrajectorySample& s) { return std::isnan(s.isovalue) ? fallback : s.isovalue; };
  if (!(t_s > samples_.front().t_s)) return at(samples_.front());  // also NaN
  if (t_s >= samples_.back().t_s) return at(samples_.back());
  const auto it = std::upper_bound(samples_.begin(), samples_.end(), t_s,
                                   [](double t, const TrajectorySample& s) { return t < s.t_s; });
  const TrajectorySample& b = *it;
  const TrajectorySample& a = *(it - 1);
  const double alpha = std::clamp((t_s - a.t_s) / (b.t_s - a.t_s), 0.0, 1.0);
  return at(a) + alpha * (at(b) - at(a));
}

Trajectory parseTrajectoryCsv(std::istream& in, const std::string& source_name) {
  std::vector<TrajectorySample> samples;
  std::string line;
  int line_number = 0;
  bool first_content_line = true;
  std::size_t header_columns = 0;  // 0: no header (8 or 9 values per row)
  auto fail = [&](const std::string& problem) {
    throw std::runtime_error(source_name + ":" + std::to_string(line_number) + ": " + problem);
  };
  while (std::getline(in, line)) {
    ++line_number;
    const std::string_view content = trim(line);
    if (content.empty() || content.front() == '#') continue;
    const std::vector<std::string_view> fields = splitComma(content);
    const bool is_first = first_content_line;
    first_content_line = false;
    double probe = 0.0;
    if (is_first && !parseDouble(fields.front(), probe)) {
      // A header line: it must name the expected columns (the pose's 8, or those and isovalue).
      bool matches = fields.size() == kPoseColumns || fields.size() == kColumns.size();
      for (std::size_t i = 0; matches && i < fields.size(); ++i) matches = lowercase(fields[i]) == kColumns[i];
      if (!matches) {
        fail("header must be '" + columnList() + "' or '" + columnList(kColumns.size()) + "', found '" +
             std::string(content) + "'");
      }
      header_columns = fields.size();
      continue;
    }
    if (header_columns != 0 ? fields.size() != header_columns
                            : fields.size() != kPoseColumns && fields.size() != kColumns.size()) {
      const std::string expected = header_columns != 0
                                       ? std::to_string(header_columns) + " comma-separated values (" +
                                             columnList(header_columns) + ", as the header says)"
                                       : "8 or 9 comma-separated values (" + columnList(kColumns.size()) + ")";
      fail("expected " + expected + ", found " + std::to_string(fields.size()));
    }
    std::array<double, 9> v{};
    v[8] = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (i == 8 && fields[i].empty()) continue;  // blank isovalue: the scene's
      if (!parseDouble(fields[i], v[i])) {
        fail("column " + std::string(kColumns[i]) + ": '" + std::string(fields[i]) + "' is not a number");
      }
      if (!std::isfinite(v[i])) fail("column " + std::string(kColumns[i]) + ": value is not finite");
    }
    TrajectorySample s;
    s.isovalue = v[8];
    s.t_s = v[0];
    s.X_WD.p_AB_m = Eigen::Vector3d(v[1], v[2], v[3]);
    s.X_WD.R_AB = Eigen::Quaterniond(v[4], v[5], v[6], v[7]);
    const double norm = s.X_WD.R_AB.coeffs().stableNorm();  // no overflow to inf for huge components
    if (!(norm > 1e-9)) fail("zero quaternion (qw, qx, qy, qz all 0)");
    s.X_WD.R_AB.coeffs() /= norm;
    if (!samples.empty() && !(s.t_s > samples.back().t_s)) {
      std::ostringstream msg;
      msg << "time " << s.t_s << " s does not increase (previous row: " << samples.back().t_s << " s)";
      fail(msg.str());
    }
    samples.push_back(s);
  }
  if (in.bad()) throw std::runtime_error(source_name + ": read error");
  if (samples.empty()) throw std::runtime_error(source_name + ": no samples (expected rows of " + columnList() + ")");
  return Trajectory(std::move(samples));
}

Trajectory loadTrajectoryCsv(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw std::runtime_error(path.string() + ": trajectory file not found");
  }
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open the trajectory file");
  return parseTrajectoryCsv(in, path.string());
}

void writeTrajectoryCsv(const Trajectory& trajectory, const std::filesystem::path& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write the trajectory file");
  const bool isovalues = trajectory.hasIsovalues();
  out << columnList(isovalues ? kColumns.size() : kPoseColumns) << '\n' << std::setprecision(17);
  for (const TrajectorySample& s : trajectory.samples()) {
    const Eigen::Quaterniond& q = s.X_WD.R_AB;
    out << s.t_s << ',' << s.X_WD.p_AB_m.x() << ',' << s.X_WD.p_AB_m.y() << ',' << s.X_WD.p_AB_m.z() << ','
        << q.w() << ',' << q.x() << ',' << q.y() << ',' << q.z();
    if (isovalues) {
      out << ',';
      if (!std::isnan(s.isovalue)) out << s.isovalue;
    }
    out << '\n';
  }
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

PushSlidePlan makePushSlideTrajectory(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                      double isovalue, const Pose& X_WT_ray_start,
                                      const PushSlideOptions& o, double max_distance_m) {
  if (!(o.approach_dir_W.norm() > 0.0)) throw std::invalid_argument("push-slide: zero approach direction");
  if (o.approach_time_s <= 0.0 || o.push_time_s <= 0.0 || o.slide_time_s <= 0.0 || o.retract_time_s <= 0.0 ||
      o.hold_s < 0.0) {
    throw std::invalid_argument("push-slide: phase durations must be positive");
  }
  const Eigen::Vector3d d = o.approach_dir_W.normalized();
  const int inside = countPointsInside(volume, shell, X_WT_ray_start, isovalue);
  if (inside > 0) {
    throw std::runtime_error("push-slide: the ray's start pose is not free (" + std::to_string(inside) +
                             " tool points inside the isosurface)");
  }
  if (max_distance_m <= 0.0) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const Eigen::Vector3d& p : shell.points_T_m()) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const double tool_size = shell.empty() ? 0.0 : (hi - lo).norm();
    max_distance_m = (volume.boundsMax_W_m() - volume.boundsMin_W_m()).norm() + tool_size;
  }
  const auto contact = firstContactDistance(volume, shell, X_WT_ray_start, d, max_distance_m, isovalue);
  if (!contact) {
    std::ostringstream msg;
    msg << "push-slide: no surface at isovalue " << isovalue << " along the ray from ("
        << X_WT_ray_start.p_AB_m.transpose() << ") m towards (" << d.transpose() << ") within "
        << max_distance_m << " m";
    throw std::runtime_error(msg.str());
  }

  Eigen::Vector3d slide = o.slide_dir_W;
  if (!(slide.norm() > 0.0)) {
    int axis = 0;
    d.cwiseAbs().minCoeff(&axis);
    slide = Eigen::Vector3d::Unit(axis);
  }
  slide = slide - slide.dot(d) * d;
  if (!(slide.norm() > 1e-9)) throw std::invalid_argument("push-slide: slide direction parallel to the approach");
  slide.normalize();

  PushSlidePlan plan;
  plan.contact_distance_m = *contact;
  plan.X_WD_contact = {X_WT_ray_start.R_AB, X_WT_ray_start.p_AB_m + *contact * d};
  const Pose& Xc = plan.X_WD_contact;
  const Eigen::Quaterniond R_slide =
      (Eigen::Quaterniond(Eigen::AngleAxisd(o.slide_rotation_rad, d.cross(slide).normalized())) * Xc.R_AB)
          .normalized();

  std::vector<TrajectorySample> keys;
  double t = 0.0;
  auto key = [&](double dt, const Eigen::Vector3d& p_W, const Eigen::Quaterniond& R) {
    if (!keys.empty() && !(dt > 0.0)) return;
    t += dt;
    keys.push_back({t, Pose{R, p_W}});
  };
  const Eigen::Vector3d p_start = Xc.p_AB_m - o.start_clearance_m * d;
  const Eigen::Vector3d p_deep = Xc.p_AB_m + o.push_depth_m * d;
  const Eigen::Vector3d p_slid = p_deep + o.slide_m * slide;
  key(0.0, p_start, Xc.R_AB);
  key(o.hold_s, p_start, Xc.R_AB);
  key(o.approach_time_s, Xc.p_AB_m, Xc.R_AB);
  key(o.push_time_s, p_deep, Xc.R_AB);
  key(o.slide_time_s, p_slid, R_slide);
  key(o.hold_s, p_slid, R_slide);
  key(o.retract_time_s, p_slid - (o.push_depth_m + o.start_clearance_m) * d, R_slide);
  key(o.hold_s, p_slid - (o.push_depth_m + o.start_clearance_m) * d, R_slide);
  plan.trajectory = Trajectory(std::move(keys));
  return plan;
}

}  // namespace vh::runtime
