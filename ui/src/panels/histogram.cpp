#include "vh/ui/panels/histogram.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkType.h>

namespace vh::ui {

double Histogram::binWidth() const noexcept {
  return counts.empty() ? 0.0 : (max_value - min_value) / static_cast<double>(counts.size());
}

int Histogram::binOf(double value) const noexcept {
  if (counts.empty()) return -1;
  const double w = binWidth();
  if (!(w > 0.0) || !std::isfinite(value)) return 0;
  const double t = std::floor((value - min_value) / w);
  return static_cast<int>(std::clamp(t, 0.0, static_cast<double>(counts.size() - 1)));
}

double Histogram::binCentre(int i) const noexcept { return min_value + (i + 0.5) * binWidth(); }

std::uint64_t Histogram::total() const noexcept {
  return std::accumulate(counts.begin(), counts.end(), std::uint64_t{0});
}

namespace {

template <typename T>
void accumulate(const T* data, vtkIdType n, int stride, Histogram& h, const std::atomic<bool>* cancel) {
  const double lo = h.min_value;
  const int bins = h.binCount();
  const double scale = bins / (h.max_value - h.min_value);
  std::uint64_t* counts = h.counts.data();
  constexpr vtkIdType kChunk = 1 << 20;  // check for cancel about every million voxels
  for (vtkIdType begin = 0; begin < n; begin += kChunk) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
      h.counts.clear();
      return;
    }
    const vtkIdType end = std::min(n, begin + kChunk);
    for (vtkIdType i = begin; i < end; ++i) {
      const double v = static_cast<double>(data[i * stride]);
      if constexpr (std::numeric_limits<T>::has_quiet_NaN) {
        if (!std::isfinite(v)) continue;
      }
      int b = static_cast<int>((v - lo) * scale);
      b = b < 0 ? 0 : (b >= bins ? bins - 1 : b);
      ++counts[b];
    }
  }
}

}  // namespace

Histogram computeHistogram(vtkImageData* image, int bins, const std::atomic<bool>* cancel) {
  Histogram h;
  if (image == nullptr || bins < 1) return h;
  vtkDataArray* scalars = image->GetPointData() != nullptr ? image->GetPointData()->GetScalars() : nullptr;
  if (scalars == nullptr || scalars->GetNumberOfTuples() == 0) return h;
  double range[2];
  scalars->GetRange(range, 0);
  if (!std::isfinite(range[0]) || !std::isfinite(range[1])) return h;
  h.min_value = range[0];
  h.max_value = range[1] > range[0] ? range[1] : range[0] + 1.0;
  h.counts.assign(static_cast<std::size_t>(bins), 0);
  const vtkIdType n = scalars->GetNumberOfTuples();
  const int stride = scalars->GetNumberOfComponents();
  switch (scalars->GetDataType()) {
    vtkTemplateMacro(accumulate(static_cast<const VTK_TT*>(scalars->GetVoidPointer(0)), n, stride, h, cancel));
    default:
      h.counts.clear();
      break;
  }
  return h;
}

Histogram computeHistogram(const std::vector<double>& values, int bins) {
  Histogram h;
  if (bins < 1) return h;
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const double v : values) {
    if (std::isfinite(v)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  if (!(lo <= hi)) return h;
  h.min_value = lo;
  h.max_value = hi > lo ? hi : lo + 1.0;
  h.counts.assign(static_cast<std::size_t>(bins), 0);
  accumulate(values.data(), static_cast<vtkIdType>(values.size()), 1, h, nullptr);
  return h;
}

}  // namespace vh::ui
