#pragma once
/// @file
/// The isovalue slider with the volume's histogram drawn behind it (log counts, so small
/// tissue classes stay visible next to the air peak), and for CT a row of tissue labels (air,
/// fat, water, soft tissue, bone) at their HU values.

#include <QSlider>

#include "vh/ui/panels/histogram.h"

namespace vh::ui {

class HistogramSlider : public QSlider {
  Q_OBJECT

 public:
  explicit HistogramSlider(QWidget* parent = nullptr);

  /// The histogram to draw and the values [value_min, value_max] (data units) the slider's
  /// range maps onto linearly; `hounsfield` adds the CT tissue labels.
  void setHistogram(Histogram histogram, double value_min, double value_max, bool hounsfield);
  void clearHistogram();
  const Histogram& histogram() const noexcept { return histogram_; }

  QSize sizeHint() const override;
  QSize minimumSizeHint() const override;

 protected:
  void paintEvent(QPaintEvent* event) override;

 private:
  /// x [px] of a data value along the handle's travel.
  double xOfValue(double value) const;

  Histogram histogram_;
  double value_min_ = 0.0;
  double value_max_ = 1.0;
  bool hounsfield_ = false;
};

}  // namespace vh::ui
