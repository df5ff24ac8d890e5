#include "vh/ui/panels/strip_chart.h"

#include <algorithm>
#include <cmath>

#include <QChart>
#include <QChartView>
#include <QLineSeries>
#include <QPen>
#include <QValueAxis>
#include <QVBoxLayout>

namespace vh::ui {
namespace {

constexpr qint64 kRedrawMs = 120;

/// A "nice" upper axis bound >= v (1, 2, 5 times a power of ten).
double niceCeil(double v) {
  if (!(v > 0.0)) return 1.0;
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= v) return m * p;
  }
  return 10.0 * p;
}

}  // namespace

StripChart::StripChart(QWidget* parent, double window_s)
    : QWidget(parent), window_s_(window_s > 0.0 ? window_s : 10.0), chart_(new QChart()) {
  force_ = new QLineSeries(chart_);
  force_->setName("|F| [N]");
  force_->setPen(QPen(QColor(230, 160, 20), 2.0));
  tick_mean_ = new QLineSeries(chart_);
  tick_mean_->setName(QString::fromUtf8("solver tick mean [\u00b5s]"));
  tick_mean_->setPen(QPen(QColor(60, 140, 220), 1.5));
  tick_max_ = new QLineSeries(chart_);
  tick_max_->setName(QString::fromUtf8("solver tick max [\u00b5s]"));
  tick_max_->setPen(QPen(QColor(60, 140, 220), 1.0, Qt::DashLine));
  jitter_ = new QLineSeries(chart_);
  jitter_->setName(QString::fromUtf8("coupling jitter [\u00b5s]"));
  jitter_->setPen(QPen(QColor(200, 60, 90), 1.0));
  chart_->addSeries(force_);
  chart_->addSeries(tick_mean_);
  chart_->addSeries(tick_max_);
  chart_->addSeries(jitter_);

  axis_t_ = new QValueAxis(chart_);
  axis_t_->setLabelFormat("%.0f s");
  axis_t_->setRange(-window_s_, 0.0);  // seconds before the newest sample
  axis_t_->setTickCount(6);
  axis_force_ = new QValueAxis(chart_);
  axis_force_->setLabelFormat("%.1f N");
  axis_force_->setRange(0.0, 1.0);
  axis_force_->setTickCount(6);  // 5 intervals: 1-2-5 ranges give round labels
  axis_tick_ = new QValueAxis(chart_);
  axis_tick_->setLabelFormat("%.0f");  // Qt Charts formats in Latin-1: the unit is in the legend
  axis_tick_->setRange(0.0, 1000.0);
  axis_tick_->setTickCount(6);
  chart_->addAxis(axis_t_, Qt::AlignBottom);
  chart_->addAxis(axis_force_, Qt::AlignLeft);
  chart_->addAxis(axis_tick_, Qt::AlignRight);
  force_->attachAxis(axis_t_);
  force_->attachAxis(axis_force_);
  for (QLineSeries* s : {tick_mean_, tick_max_, jitter_}) {
    s->attachAxis(axis_t_);
    s->attachAxis(axis_tick_);
  }
  chart_->legend()->setAlignment(Qt::AlignTop);
  QFont small = chart_->legend()->font();
  small.setPointSizeF(std::max(7.0, small.pointSizeF() * 0.85));
  chart_->legend()->setFont(small);
  for (QValueAxis* a : {axis_t_, axis_force_, axis_tick_}) a->setLabelsFont(small);
  chart_->setMargins(QMargins(2, 2, 2, 2));
  chart_->setBackgroundRoundness(0);
  chart_->setAnimationOptions(QChart::NoAnimation);

  view_ = new QChartView(chart_, this);
  view_->setObjectName("stripChart");
  view_->setRenderHint(QPainter::Antialiasing, false);
  view_->setMinimumHeight(160);
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->addWidget(view_);
  since_redraw_.start();
}

void StripChart::addSample(double t_s, double force_N, double mean_tick_us, double max_tick_us, double jitter_us) {
  if (!std::isfinite(t_s)) return;
  auto finite = [](double v) { return std::isfinite(v) ? v : 0.0; };
  samples_.push_back({t_s, finite(force_N), finite(mean_tick_us), finite(max_tick_us), finite(jitter_us)});
  while (!samples_.empty() && samples_.front().t_s < t_s - window_s_ - 1.0) samples_.pop_front();
  if (since_redraw_.elapsed() >= kRedrawMs) redraw();
}

void StripChart::flush() { redraw(); }

void StripChart::redraw() {
  since_redraw_.restart();
  // x = time relative to the newest sample; each series is replaced at once (one repaint).
  const double now = samples_.empty() ? 0.0 : samples_.back().t_s;
  QList<QPointF> force, mean, max, jitter;
  force.reserve(static_cast<qsizetype>(samples_.size()));
  mean.reserve(static_cast<qsizetype>(samples_.size()));
  max.reserve(static_cast<qsizetype>(samples_.size()));
  jitter.reserve(static_cast<qsizetype>(samples_.size()));
  double top_force = 0.0, top_tick = 0.0;
  for (const Sample& s : samples_) {
    const double x = s.t_s - now;
    force.append(QPointF(x, s.force_N));
    mean.append(QPointF(x, s.mean_us));
    max.append(QPointF(x, s.max_us));
    jitter.append(QPointF(x, s.jitter_us));
    top_force = std::max(top_force, s.force_N);
    top_tick = std::max({top_tick, s.mean_us, s.max_us, s.jitter_us});
  }
  force_->replace(force);
  tick_mean_->replace(mean);
  tick_max_->replace(max);
  jitter_->replace(jitter);
  axis_force_->setRange(0.0, niceCeil(std::max(0.5, 1.1 * top_force)));
  axis_tick_->setRange(0.0, niceCeil(std::max(100.0, 1.1 * top_tick)));
}

void StripChart::addSnapshot(const runtime::HapticSnapshot& snapshot) {
  if (!since_start_.isValid()) since_start_.start();
  addSample(1e-3 * static_cast<double>(since_start_.elapsed()), snapshot.force_W_N.norm(), snapshot.solver.mean_tick_us,
            snapshot.solver.max_tick_us, snapshot.coupling.jitter_us);
}

void StripChart::clear() {
  samples_.clear();
  redraw();
}

int StripChart::sampleCount() const { return static_cast<int>(samples_.size()); }

}  // namespace vh::ui
