#pragma once
/// @file
/// A live strip chart (Qt Charts) of the haptic threads: the force magnitude |F| [N] on the left
/// axis; on the right axis [us] the solver thread's tick time (mean and max over the last second)
/// and the coupling thread's period jitter (largest deviation of its wake-up interval from the
/// period over the last second); over the last `window_s` seconds (the x axis is time relative to
/// the newest sample, -window..0 s). A legend names the series. Fed from the display timer with
/// snapshot values; redraws at most ~8 times a second so it costs little on software rendering.

#include <deque>

#include <QElapsedTimer>
#include <QWidget>

#include "vh/runtime/haptic_thread.h"

class QChart;
class QChartView;
class QLineSeries;
class QValueAxis;

namespace vh::ui {

class StripChart : public QWidget {
  Q_OBJECT

 public:
  explicit StripChart(QWidget* parent = nullptr, double window_s = 10.0);

  /// One sample at time t_s [s] (any monotonic clock): |F| [N], the solver's mean and max tick
  /// time [us] and the coupling thread's jitter [us] (HapticSnapshot::solver / ::coupling).
  void addSample(double t_s, double force_N, double mean_tick_us, double max_tick_us, double jitter_us = 0.0);
  /// A haptic snapshot's |F|, solver tick times and coupling jitter, at the time since the
  /// chart was made [s].
  void addSnapshot(const runtime::HapticSnapshot& snapshot);
  /// Redraws with every sample so far now (normally at most ~8 times a second).
  void flush();
  /// Forgets every sample (e.g. a new scene).
  void clear();
  /// Samples held (including those not drawn yet).
  int sampleCount() const;
  QChartView* chartView() const noexcept { return view_; }

 private:
  void redraw();

  double window_s_;
  QChart* chart_;
  QChartView* view_;
  QLineSeries* force_;
  QLineSeries* tick_mean_;
  QLineSeries* tick_max_;
  QLineSeries* jitter_;
  QValueAxis* axis_t_;
  QValueAxis* axis_force_;
  QValueAxis* axis_tick_;
  struct Sample {
    double t_s, force_N, mean_us, max_us, jitter_us;
  };
  std::deque<Sample> samples_;  // oldest first, at most window_s (+1 s) old
  QElapsedTimer since_redraw_;
  QElapsedTimer since_start_;  // addSnapshot()'s time base
};

}  // namespace vh::ui
