// Segments in a scene (see segments.h).
#include "vh/runtime/segments.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace vh::runtime {
namespace {

bool contains(const std::vector<int>& v, int s) { return std::find(v.begin(), v.end(), s) != v.end(); }

std::vector<int> resolve(const io::LoadedSegmentation& seg, const std::vector<std::string>& names, const char* what,
                         const std::string& source) {
  std::vector<int> out;
  for (const auto& n : names) {
    const int s = seg.find(n);
    if (s < 0) {
      std::string known;
      for (const auto& info : seg.segments) known += (known.empty() ? "\"" : ", \"") + info.name + "\"";
      throw std::runtime_error(source + ": segmentation." + what + ": no segment \"" + n + "\" in " +
                               seg.source.filename().string() + " (it has " + known + ")");
    }
    if (!contains(out, s)) out.push_back(s);
  }
  return out;
}

/// The distance field of segment `info`'s voxels (its label in its layer), stored up to
/// kProximityRange_m around them.
std::shared_ptr<const haptics::DistanceField> distanceFieldOf(const io::LoadedSegmentation& seg,
                                                              const io::SegmentInfo& info) {
  if (info.layer < 0 || static_cast<std::size_t>(info.layer) >= seg.layers.size() ||
      !seg.layers[static_cast<std::size_t>(info.layer)]) {
    return std::make_shared<const haptics::DistanceField>();
  }
  const haptics::ScalarVolume& layer = *seg.layers[static_cast<std::size_t>(info.layer)];
  const auto& g = layer.geometry();
  std::vector<std::uint8_t> mask(g.voxelCount(), 0);
  std::size_t idx = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++idx)
        mask[idx] = std::lround(layer.voxel(i, j, k)) == info.label_value ? 1 : 0;
  return std::make_shared<const haptics::DistanceField>(haptics::DistanceField::FromMask(g, mask, kProximityRange_m));
}

/// The thresholds of every segment from the spec (names resolved), defaults for the rest.
std::vector<ProximityThresholds> thresholdsOf(const io::LoadedSegmentation& seg, const ProximitySpec& spec,
                                              const std::vector<int>& critical, const std::string& source) {
  std::vector<ProximityThresholds> out(seg.segments.size(), spec.defaults);
  for (const auto& [name, t] : spec.per_segment) {
    const int s = resolve(seg, {name}, "proximity.per_segment", source).front();
    if (!contains(critical, s)) {
      throw std::runtime_error(source + ": segmentation.proximity.per_segment: \"" + name +
                               "\" is not a critical segment (list it in segmentation.critical)");
    }
    out[static_cast<std::size_t>(s)] = t;
  }
  return out;
}

}  // namespace

SegmentSet::SegmentSet(io::LoadedSegmentation seg, std::vector<int> felt, std::vector<int> shown,
                       std::vector<int> critical, double smoothing_voxels, std::vector<ProximityThresholds> thresholds)
    : seg_(std::move(seg)),
      felt_(std::move(felt)),
      shown_(std::move(shown)),
      critical_(std::move(critical)),
      smoothing_voxels_(smoothing_voxels) {
  for (const auto* list : {&felt_, &shown_, &critical_}) {
    for (const int s : *list) {
      if (s < 0 || static_cast<std::size_t>(s) >= seg_.segments.size()) {
        throw std::invalid_argument("SegmentSet: no segment " + std::to_string(s));
      }
    }
  }
  if (!felt_.empty()) {
    felt_field_ = io::segmentIndicatorField(seg_, felt_, smoothing_voxels_);
    for (const int s : felt_) {
      const auto& info = seg_.segments[static_cast<std::size_t>(s)];
      felt_labels_.push_back({s, info.layer, info.label_value});
    }
  }
  for (const int s : critical_) critical_fields_.push_back(distanceFieldOf(seg_, seg_.segments[static_cast<std::size_t>(s)]));
  if (thresholds.empty()) thresholds.assign(seg_.segments.size(), ProximityThresholds{});
  setThresholds(std::move(thresholds));
}

void SegmentSet::setThresholds(std::vector<ProximityThresholds> thresholds) {
  if (thresholds.size() != seg_.segments.size()) {
    throw std::invalid_argument("SegmentSet: " + std::to_string(thresholds.size()) + " proximity thresholds for " +
                                std::to_string(seg_.segments.size()) + " segments");
  }
  for (std::size_t s = 0; s < thresholds.size(); ++s)
    validateProximityThresholds(thresholds[s], "proximity of \"" + seg_.segments[s].name + "\"");
  thresholds_ = std::move(thresholds);
}

std::shared_ptr<const SegmentSet> SegmentSet::withThresholds(std::vector<ProximityThresholds> thresholds) const {
  std::shared_ptr<SegmentSet> out(new SegmentSet());
  out->seg_ = seg_;
  out->felt_ = felt_;
  out->shown_ = shown_;
  out->critical_ = critical_;
  out->smoothing_voxels_ = smoothing_voxels_;
  out->felt_field_ = felt_field_;
  out->critical_fields_ = critical_fields_;
  out->felt_labels_ = felt_labels_;
  out->setThresholds(std::move(thresholds));
  return out;
}

std::shared_ptr<const SegmentSet> SegmentSet::fromSpec(io::LoadedSegmentation seg, const SegmentationSpec& spec,
                                                       const std::string& source) {
  std::vector<int> felt = resolve(seg, spec.felt, "felt", source);
  std::vector<int> shown;
  if (spec.shown) {
    shown = resolve(seg, *spec.shown, "shown", source);
  } else {
    for (std::size_t s = 0; s < seg.segments.size(); ++s) shown.push_back(static_cast<int>(s));
  }
  std::vector<int> critical = resolve(seg, spec.critical, "critical", source);
  std::vector<ProximityThresholds> thresholds = thresholdsOf(seg, spec.proximity, critical, source);
  return std::make_shared<const SegmentSet>(std::move(seg), std::move(felt), std::move(shown), std::move(critical),
                                            spec.smoothing_voxels, std::move(thresholds));
}

bool SegmentSet::isFelt(int s) const noexcept { return contains(felt_, s); }
bool SegmentSet::isShown(int s) const noexcept { return contains(shown_, s); }
bool SegmentSet::isCritical(int s) const noexcept { return contains(critical_, s); }

std::string SegmentSet::name(int s) const {
  if (s < 0 || static_cast<std::size_t>(s) >= seg_.segments.size()) return {};
  return seg_.segments[static_cast<std::size_t>(s)].name;
}

int SegmentSet::segmentAt(const Eigen::Vector3d& p_W_m) const noexcept {
  if (felt_labels_.empty() || seg_.layers.empty() || !p_W_m.allFinite()) return -1;
  const haptics::ScalarVolume& grid = *seg_.layers.front();
  const Eigen::Vector3d g = grid.gridCoordinates(p_W_m);
  const auto& d = grid.geometry().dims;
  if (!g.allFinite()) return -1;
  std::array<int, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    lo[static_cast<std::size_t>(a)] = std::max(0, static_cast<int>(std::floor(g[a])) - 1);
    hi[static_cast<std::size_t>(a)] = std::min(d[static_cast<std::size_t>(a)] - 1, static_cast<int>(std::floor(g[a])) + 2);
    if (lo[static_cast<std::size_t>(a)] > hi[static_cast<std::size_t>(a)]) return -1;  // far outside the grid
  }
  int best = -1;
  double best_d2 = 4.0 + 1e-9;  // two voxels
  for (int k = lo[2]; k <= hi[2]; ++k) {
    for (int j = lo[1]; j <= hi[1]; ++j) {
      for (int i = lo[0]; i <= hi[0]; ++i) {
        const double d2 = (Eigen::Vector3d(i, j, k) - g).squaredNorm();
        if (d2 >= best_d2) continue;
        for (const FeltLabel& f : felt_labels_) {
          if (seg_.label(f.layer, i, j, k) == f.label) {
            best = f.segment;
            best_d2 = d2;
            break;
          }
        }
      }
    }
  }
  return best;
}

int SegmentSet::segmentOf(std::span<const haptics::Contact> contacts) const noexcept {
  if (contacts.empty() || felt_labels_.empty()) return -1;
  constexpr std::size_t kMaxExamined = 16;
  constexpr std::size_t kMaxSegments = 16;
  std::array<int, kMaxSegments> segments{};
  std::array<int, kMaxSegments> votes{};
  std::size_t distinct = 0;
  const std::size_t step = std::max<std::size_t>(1, contacts.size() / kMaxExamined);
  for (std::size_t c = 0; c < contacts.size(); c += step) {
    const int s = segmentAt(contacts[c].p_W_m);
    if (s < 0) continue;
    std::size_t n = 0;
    while (n < distinct && segments[n] != s) ++n;
    if (n == distinct) {
      if (distinct == kMaxSegments) continue;
      segments[distinct++] = s;
    }
    ++votes[n];
  }
  int best = -1, best_votes = 0;
  for (std::size_t n = 0; n < distinct; ++n) {
    if (votes[n] > best_votes) best = segments[n], best_votes = votes[n];
  }
  return best;
}

void SegmentNameTable::set(const SegmentSet* set) {
  std::vector<std::string> names;
  if (set != nullptr) {
    for (int s = 0; s < static_cast<int>(set->size()); ++s) names.push_back(set->name(s));
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  names_ = std::move(names);
}

std::string SegmentNameTable::name(int s) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return s >= 0 && static_cast<std::size_t>(s) < names_.size() ? names_[static_cast<std::size_t>(s)] : std::string();
}

SegmentContactTally::SegmentContactTally(const std::vector<std::string>& names, const std::vector<bool>& critical) {
  if (names.size() != critical.size()) throw std::invalid_argument("SegmentContactTally: names and critical differ in length");
  for (std::size_t s = 0; s < names.size(); ++s) {
    SegmentContact c;
    c.name = names[s];
    c.critical = critical[s];
    segments_.push_back(std::move(c));
  }
}

void SegmentContactTally::add(int segment, double force_N, double dt_s) noexcept {
  if (segment >= 0 && static_cast<std::size_t>(segment) < segments_.size()) {
    SegmentContact& c = segments_[static_cast<std::size_t>(segment)];
    ++c.ticks;
    c.time_in_contact_s += dt_s;
    if (std::isfinite(force_N)) c.peak_force_N = std::max(c.peak_force_N, force_N);
    if (segment != previous_) ++c.touches;
  }
  previous_ = segment;
}

}  // namespace vh::runtime
