// The opening isovalue of a scan, from its modality and values (vh/runtime/default_isovalue.h).
#include "vh/runtime/default_isovalue.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace vh::runtime {
namespace {

constexpr double kBoneHU = 400.0;
constexpr double kMaxSamples = 2.0e6;  // voxels read for the histogram at most (about)

/// The histogram of `field`'s values in `bins` equal bins over [minValue, maxValue], sampled on a
/// regular stride so that about kMaxSamples voxels are read.
std::vector<double> histogramOf(const haptics::ScalarVolume& field, int bins) {
  const double lo = field.minValue();
  const double per_bin = bins / (field.maxValue() - lo);
  const auto& dims = field.geometry().dims;
  const double total = static_cast<double>(dims[0]) * dims[1] * dims[2];
  const int stride = std::max(1, static_cast<int>(std::ceil(std::cbrt(total / kMaxSamples))));
  std::vector<double> count(static_cast<std::size_t>(bins), 0.0);
  for (int k = 0; k < dims[2]; k += stride) {
    for (int j = 0; j < dims[1]; j += stride) {
      for (int i = 0; i < dims[0]; i += stride) {
        const double v = field.voxel(i, j, k);
        if (!std::isfinite(v)) continue;
        count[static_cast<std::size_t>(std::clamp(static_cast<int>((v - lo) * per_bin), 0, bins - 1))] += 1.0;
      }
    }
  }
  return count;
}

}  // namespace

double triangleThreshold(const haptics::ScalarVolume& field, int bins) {
  const double lo = field.minValue();
  const double hi = field.maxValue();
  if (!(hi > lo) || bins < 3) return 0.5 * (lo + hi);
  const std::vector<double> h = histogramOf(field, bins);
  const int peak = static_cast<int>(std::max_element(h.begin(), h.end()) - h.begin());
  // The far end: the last (or first) non-empty bin on the longer side of the peak.
  int last = bins - 1;
  while (last > peak && h[static_cast<std::size_t>(last)] == 0.0) --last;
  int first = 0;
  while (first < peak && h[static_cast<std::size_t>(first)] == 0.0) ++first;
  const bool upward = last - peak >= peak - first;
  const int end = upward ? last : first;
  if (end == peak) return 0.5 * (lo + hi);
  // The bin farthest below the line from (peak, h[peak]) to (end, h[end]) (Zack et al. 1977).
  const double x0 = peak, y0 = h[static_cast<std::size_t>(peak)];
  const double dx = end - peak, dy = h[static_cast<std::size_t>(end)] - y0;
  double best = -1.0;
  int best_bin = peak;
  for (int b = peak; upward ? b <= end : b >= end; b += upward ? 1 : -1) {
    const double distance = std::abs(dy * (b - x0) - dx * (h[static_cast<std::size_t>(b)] - y0));
    if (distance > best) {
      best = distance;
      best_bin = b;
    }
  }
  // The level between the background's side and the rest: the far edge of the chosen bin.
  return lo + (best_bin + (upward ? 1 : 0)) * (hi - lo) / bins;
}

bool inHounsfieldUnits(const io::LoadedVolume& volume) {
  return volume.info.modality == "CT" || volume.info.value_unit == "HU";
}

double defaultIsovalue(const io::LoadedVolume& volume) {
  const haptics::ScalarVolume& f = *volume.field;
  const std::string& modality = volume.info.modality;
  if (inHounsfieldUnits(volume) && f.minValue() < kBoneHU && f.maxValue() > kBoneHU) return kBoneHU;
  if (modality == "MR" || modality == "PT") return triangleThreshold(f);
  return 0.5 * (f.minValue() + f.maxValue());
}

}  // namespace vh::runtime
