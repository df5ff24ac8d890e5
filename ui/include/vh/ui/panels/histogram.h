#pragma once
/// @file
/// The histogram of a volume's values (data units, HU for CT), computed once at load on the
/// loader thread and drawn behind the isovalue slider so the user sees where the tissue classes
/// lie. No Qt.

#include <atomic>
#include <cstdint>
#include <vector>

class vtkImageData;

namespace vh::ui {

/// Equal-width bins over [min_value, max_value] in the data's units.
struct Histogram {
  double min_value = 0.0;              ///< Lower edge of the first bin (data units).
  double max_value = 1.0;              ///< Upper edge of the last bin (data units).
  std::vector<std::uint64_t> counts;   ///< Voxels per bin (size = bin count; empty: none).

  bool empty() const noexcept { return counts.empty(); }
  int binCount() const noexcept { return static_cast<int>(counts.size()); }
  /// Width of one bin (data units); 0 when empty.
  double binWidth() const noexcept;
  /// Bin holding `value` (clamped to the first / last bin); -1 when empty.
  int binOf(double value) const noexcept;
  /// Centre of bin i (data units).
  double binCentre(int i) const noexcept;
  /// Sum of all counts (voxels).
  std::uint64_t total() const noexcept;
};

/// Histogram of the first scalar component of `image` (any VTK scalar type) with `bins` bins
/// over the scalars' range. Non-finite values are skipped. O(voxels), no allocation beyond the
/// bins; safe on any thread as long as nobody modifies the image meanwhile.
/// @param cancel when set and it becomes true, returns early with an empty histogram.
/// @return empty for a null image, no scalars, or bins < 1.
Histogram computeHistogram(vtkImageData* image, int bins = 256,
                           const std::atomic<bool>* cancel = nullptr);

/// The same over a plain array of values (tests, synthetic data): range = [min, max] of the
/// finite values (a constant array gets one unit of width).
Histogram computeHistogram(const std::vector<double>& values, int bins = 256);

}  // namespace vh::ui
