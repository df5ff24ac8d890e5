// The Replay dock's timeline of vh/ui/replay/force_timeline.h.
#include "vh/ui/replay/force_timeline.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include <QMouseEvent>
#include <QPainter>
#include <QPainterPath>

namespace vh::ui {

ForceTimeline::ForceTimeline(QWidget* parent) : QWidget(parent) {
  setObjectName("forceTimeline");
  setMinimumHeight(90);
  setMouseTracking(false);
  setToolTip("|F| over the recording; click or drag to move in time. Lines: markers.");
}

QSize ForceTimeline::sizeHint() const { return {600, 120}; }

void ForceTimeline::setSamples(std::vector<double> time_s, std::vector<double> force_N) {
  if (time_s.size() != force_N.size()) throw std::invalid_argument("ForceTimeline: times and forces differ in length");
  time_s_ = std::move(time_s);
  force_N_ = std::move(force_N);
  max_force_N_ = 0.0;
  for (double f : force_N_) {
    if (std::isfinite(f)) max_force_N_ = std::max(max_force_N_, f);
  }
  update();
}

void ForceTimeline::setMarkers(std::vector<double> time_s, QStringList labels) {
  marker_s_ = std::move(time_s);
  marker_labels_ = std::move(labels);
  update();
}

void ForceTimeline::setCursor_s(double t_s) {
  cursor_s_ = t_s;
  update();
}

QRectF ForceTimeline::plotRect() const { return QRectF(50.0, 6.0, std::max(10.0, width() - 58.0), std::max(10.0, height() - 24.0)); }

double ForceTimeline::timeAtX(double x) const {
  if (time_s_.empty()) return 0.0;
  const QRectF r = plotRect();
  const double u = std::clamp((x - r.left()) / r.width(), 0.0, 1.0);
  return time_s_.front() + u * duration_s();
}

double ForceTimeline::xAtTime(double t_s) const {
  const QRectF r = plotRect();
  const double d = duration_s();
  if (time_s_.empty() || !(d > 0.0)) return r.left();
  return r.left() + std::clamp((t_s - time_s_.front()) / d, 0.0, 1.0) * r.width();
}

void ForceTimeline::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.setRenderHint(QPainter::Antialiasing, true);
  p.fillRect(rect(), QColor(24, 27, 33));
  const QRectF r = plotRect();
  p.setPen(QColor(70, 76, 88));
  p.drawRect(r);
  p.setPen(QColor(180, 186, 196));
  const double top_N = max_force_N_ > 0.0 ? max_force_N_ * 1.1 : 1.0;
  p.drawText(QRectF(0, r.top() - 2, 46, 14), Qt::AlignRight | Qt::AlignTop, QString::number(top_N, 'g', 2) + " N");
  p.drawText(QRectF(0, r.bottom() - 12, 46, 14), Qt::AlignRight | Qt::AlignBottom, "0 N");
  if (!time_s_.empty()) {
    p.drawText(QRectF(r.left(), r.bottom() + 2, 80, 14), Qt::AlignLeft | Qt::AlignTop,
               QString("%1 s").arg(time_s_.front(), 0, 'f', 1));
    p.drawText(QRectF(r.right() - 80, r.bottom() + 2, 80, 14), Qt::AlignRight | Qt::AlignTop,
               QString("%1 s").arg(time_s_.back(), 0, 'f', 1));
  }
  // |F|: per pixel column the largest value of the samples under it.
  const int columns = std::max(1, static_cast<int>(r.width()));
  if (time_s_.size() >= 2) {
    std::vector<double> column_max(static_cast<std::size_t>(columns), -1.0);
    for (std::size_t i = 0; i < time_s_.size(); ++i) {
      const int c = std::clamp(static_cast<int>(xAtTime(time_s_[i]) - r.left()), 0, columns - 1);
      const double f = std::isfinite(force_N_[i]) ? force_N_[i] : 0.0;
      column_max[static_cast<std::size_t>(c)] = std::max(column_max[static_cast<std::size_t>(c)], f);
    }
    QPainterPath curve;
    curve.moveTo(r.left(), r.bottom());
    double last = 0.0;
    for (int c = 0; c < columns; ++c) {
      double f = column_max[static_cast<std::size_t>(c)];
      if (f < 0.0) f = last;  // no sample under this column: hold
      last = f;
      curve.lineTo(r.left() + c, r.bottom() - std::min(1.0, f / top_N) * r.height());
    }
    curve.lineTo(r.right(), r.bottom());
    curve.closeSubpath();
    p.fillPath(curve, QColor(240, 200, 60, 110));
    p.setPen(QPen(QColor(250, 210, 70), 1.2));
    p.drawPath(curve);
  }
  // Markers.
  p.setPen(QPen(QColor(90, 200, 255), 1.0, Qt::DashLine));
  for (std::size_t i = 0; i < marker_s_.size(); ++i) {
    const double x = xAtTime(marker_s_[i]);
    p.drawLine(QPointF(x, r.top()), QPointF(x, r.bottom()));
    if (static_cast<qsizetype>(i) < marker_labels_.size()) {
      p.drawText(QPointF(x + 3, r.top() + 12), marker_labels_[static_cast<qsizetype>(i)]);
    }
  }
  // Cursor.
  const double x = xAtTime(cursor_s_);
  p.setPen(QPen(QColor(255, 80, 80), 2.0));
  p.drawLine(QPointF(x, r.top()), QPointF(x, r.bottom()));
}

void ForceTimeline::mousePressEvent(QMouseEvent* event) {
  if (event->button() == Qt::LeftButton && !time_s_.empty()) emit scrubbed(timeAtX(event->position().x()));
}

void ForceTimeline::mouseMoveEvent(QMouseEvent* event) {
  if ((event->buttons() & Qt::LeftButton) != 0 && !time_s_.empty()) emit scrubbed(timeAtX(event->position().x()));
}

}  // namespace vh::ui
