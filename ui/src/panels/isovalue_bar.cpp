#include "vh/ui/panels/isovalue_bar.h"
#include "vh/ui/panels/range_spin_box.h"

#include <algorithm>
#include <cmath>
#include <exception>

#include <QDoubleSpinBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QSignalBlocker>

#include "vh/ui/panels/histogram_slider.h"

namespace vh::ui {
namespace {

constexpr int kSliderSteps = 1000;

int decimalsFor(double range) {
  if (range >= 100.0) return 0;
  if (range >= 1.0) return 2;
  return 4;
}

}  // namespace

ValueUnit valueUnitOf(const io::VolumeInfo& info) {
  const std::string& u = info.value_unit;
  if (u == "HU") return {u, "Hounsfield units (CT): air -1000, water 0, bone 400 and above"};
  if (u == "SUVbw") return {u, "standardised uptake value (body weight): the activity per gram over the dose per gram of body"};
  if (u == "Bq/ml") return {u, "activity concentration in Bq/ml as stored: the header lacks what SUV needs (see Help > Load Notes)"};
  if (!u.empty()) return {u, u + ", as the file names it"};
  if (info.modality == "MR") {
    return {"a.u.", "arbitrary units: MR intensities are the scanner's, with no physical scale; they differ between scanners and series"};
  }
  if (info.modality == "PT") return {"a.u.", "arbitrary units: PET values as stored, the header names no unit (see Help > Load Notes)"};
  return {"a.u.", "arbitrary units: the file names no unit for its values"};
}

IsovalueBar::IsovalueBar(runtime::Session& session, QWidget* parent) : QWidget(parent), session_(session) {
  auto* layout = new QHBoxLayout(this);
  layout->setContentsMargins(0, 0, 0, 0);
  label_ = new QLabel("Isovalue", this);
  slider_ = new HistogramSlider(this);
  slider_->setObjectName("isovalueSlider");
  slider_->setRange(0, kSliderSteps);
  slider_->setMinimumWidth(240);
  slider_->setToolTip(
      "Isosurface value: the rendered and the felt surface follow it live. Behind the slider: the "
      "volume's histogram (log scale).");
  spin_ = new RangeSpinBox("the isovalue", this);
  spin_->setObjectName("isovalueSpinBox");
  spin_->setKeyboardTracking(false);
  spin_->setMinimumWidth(90);
  spin_->setToolTip("Isovalue in the data's units (HU for CT, SUV or Bq/ml for PET, arbitrary units for MR)");
  layout->addWidget(label_);
  layout->addWidget(slider_, 1);
  layout->addWidget(spin_);

  connect(slider_, &QSlider::valueChanged, this, [this](int position) { apply(sliderToValue(position)); });
  connect(slider_, &QSlider::sliderPressed, this, &IsovalueBar::dragStarted);
  connect(slider_, &QSlider::sliderReleased, this, &IsovalueBar::dragEnded);
  connect(spin_, &QDoubleSpinBox::valueChanged, this, [this](double value) { apply(value); });
  observer_ = session_.addObserver([this](runtime::SessionChange what) { showSession(what); });
  showSession(runtime::SessionChange::kScene);
}

IsovalueBar::~IsovalueBar() { session_.removeObserver(observer_); }

void IsovalueBar::setHistogram(const Histogram& histogram, const std::string& unit) {
  const auto [lo, hi] = session_.valueRange();
  slider_->setHistogram(histogram, lo, hi, unit == "HU");
}

void IsovalueBar::step(int direction) { apply(session_.isovalue() + direction * spin_->singleStep()); }

void IsovalueBar::apply(double value) {
  try {
    session_.setIsovalue(value);
  } catch (const std::exception& e) {
    showSession(runtime::SessionChange::kIsovalue);  // the value kept
    emit message(QString("The isovalue stays at %1: %2").arg(session_.isovalue(), 0, 'g', 6).arg(e.what()), 10000);
  }
}

double IsovalueBar::sliderToValue(int position) const {
  const auto [lo, hi] = session_.valueRange();
  return lo + (hi - lo) * static_cast<double>(position) / kSliderSteps;
}

int IsovalueBar::valueToSlider(double value) const {
  const auto [lo, hi] = session_.valueRange();
  const double t = (value - lo) / (hi - lo);
  return static_cast<int>(std::lround(std::clamp(t, 0.0, 1.0) * kSliderSteps));
}

void IsovalueBar::showSession(runtime::SessionChange what) {
  if (!runtime::has(what, runtime::SessionChange::kScene) && !runtime::has(what, runtime::SessionChange::kIsovalue)) {
    return;
  }
  const bool on = session_.hasScene();
  slider_->setEnabled(on);
  spin_->setEnabled(on);
  const QSignalBlocker block_slider(slider_);
  const QSignalBlocker block_spin(spin_);
  if (runtime::has(what, runtime::SessionChange::kScene)) {
    const auto [lo, hi] = session_.valueRange();
    const double range = hi - lo;
    spin_->setDecimals(decimalsFor(range));
    spin_->setRange(lo, hi);
    spin_->setSingleStep(range >= 100.0 ? std::max(1.0, std::round(range / 200.0)) : range / 200.0);
    if (!on) slider_->clearHistogram();
    if (on) {
      const ValueUnit unit = valueUnitOf(session_.loaded().volume.info);
      label_->setText(QString::fromStdString("Isovalue [" + unit.symbol + "]"));
      label_->setToolTip(QString::fromStdString("Isovalue in " + unit.symbol + ": " + unit.meaning));
    } else {
      label_->setText("Isovalue");
      label_->setToolTip({});
    }
  }
  if (runtime::has(what, runtime::SessionChange::kScene)) {
    // Soft tissue is rebuilt for each new surface (seconds): the slider applies where it is
    // released, not at every step of a drag.
    const bool tissue = on && session_.live().tissue.has_value();
    slider_->setTracking(!tissue);
    slider_->setToolTip(tissue ? "Isosurface value. This scene has soft tissue: its region and compliance are "
                                 "rebuilt for the new surface where the slider is released (the force ramps to "
                                 "zero meanwhile). Behind the slider: the volume's histogram (log scale)."
                               : "Isosurface value: the rendered and the felt surface follow it live. Behind the "
                                 "slider: the volume's histogram (log scale).");
  }
  if (on) {
    spin_->setValue(session_.isovalue());
    slider_->setValue(valueToSlider(session_.isovalue()));
  }
}

}  // namespace vh::ui
