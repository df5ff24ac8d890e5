#include "vh/ui/panels/histogram_slider.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <QPainter>
#include <QPainterPath>
#include <QStyle>
#include <QStyleOptionSlider>

namespace vh::ui {
namespace {

constexpr int kLabelRow = 12;  // px under the histogram for the CT labels

struct Tissue {
  double hu;
  const char* name;
};
// In order of priority: a label that would overlap one drawn before it is left out.
constexpr Tissue kTissues[] = {{-1000, "air"}, {40, "soft tissue"}, {700, "bone"}, {-600, "lung"}, {-100, "fat"},
                               {2500, "metal"}};

}  // namespace

HistogramSlider::HistogramSlider(QWidget* parent) : QSlider(Qt::Horizontal, parent) {
  setMinimumHeight(40);
}

void HistogramSlider::setHistogram(Histogram histogram, double value_min, double value_max, bool hounsfield) {
  histogram_ = std::move(histogram);
  value_min_ = value_min;
  value_max_ = value_max > value_min ? value_max : value_min + 1.0;
  hounsfield_ = hounsfield;
  updateGeometry();
  update();
}

void HistogramSlider::clearHistogram() {
  histogram_ = {};
  update();
}

QSize HistogramSlider::sizeHint() const {
  const QSize s = QSlider::sizeHint();
  return {std::max(s.width(), 300), std::max(s.height(), hounsfield_ ? 44 : 36)};
}

QSize HistogramSlider::minimumSizeHint() const {
  const QSize s = QSlider::minimumSizeHint();
  return {std::max(s.width(), 120), std::max(s.height(), 36)};
}

double HistogramSlider::xOfValue(double value) const {
  QStyleOptionSlider opt;
  initStyleOption(&opt);
  const QRect groove = style()->subControlRect(QStyle::CC_Slider, &opt, QStyle::SC_SliderGroove, this);
  const QRect handle = style()->subControlRect(QStyle::CC_Slider, &opt, QStyle::SC_SliderHandle, this);
  // The handle's centre travels from groove.left + handle/2 to groove.right - handle/2.
  const double x0 = groove.left() + 0.5 * handle.width();
  const double x1 = groove.right() - 0.5 * handle.width();
  const double t = (value - value_min_) / (value_max_ - value_min_);
  return x0 + std::clamp(t, 0.0, 1.0) * (x1 - x0);
}

void HistogramSlider::paintEvent(QPaintEvent* event) {
  if (!histogram_.empty()) {
    QPainter p(this);
    p.setRenderHint(QPainter::Antialiasing, true);
    const int label_h = hounsfield_ ? kLabelRow : 0;
    const QRectF area(0, 1, width(), height() - 2 - label_h);
    // Log counts, normalised to the tallest bin.
    double top = 0.0;
    for (const std::uint64_t c : histogram_.counts) top = std::max(top, std::log1p(static_cast<double>(c)));
    if (top > 0.0) {
      QPainterPath path;
      path.moveTo(xOfValue(histogram_.min_value), area.bottom());
      for (int i = 0; i < histogram_.binCount(); ++i) {
        const double h = std::log1p(static_cast<double>(histogram_.counts[static_cast<std::size_t>(i)])) / top;
        const double y = area.bottom() - h * area.height();
        path.lineTo(xOfValue(histogram_.min_value + i * histogram_.binWidth()), y);
        path.lineTo(xOfValue(histogram_.min_value + (i + 1) * histogram_.binWidth()), y);
      }
      path.lineTo(xOfValue(histogram_.max_value), area.bottom());
      path.closeSubpath();
      const QColor fill = palette().color(QPalette::Highlight);
      QColor translucent = fill;
      translucent.setAlpha(70);
      p.fillPath(path, translucent);
      QColor edge = fill;
      edge.setAlpha(140);
      p.setPen(QPen(edge, 1.0));
      p.drawPath(path);
    }
    if (hounsfield_) {
      QFont f = font();
      f.setPointSizeF(std::max(6.0, f.pointSizeF() * 0.75));
      p.setFont(f);
      p.setPen(palette().color(QPalette::PlaceholderText));
      std::vector<std::pair<double, double>> taken;  // [x0, x1] of the labels drawn
      for (const Tissue& t : kTissues) {
        if (t.hu < value_min_ || t.hu > value_max_) continue;
        const double x = xOfValue(t.hu);
        const QString name = QString::fromLatin1(t.name);
        const double w = p.fontMetrics().horizontalAdvance(name);
        const double x0 = std::clamp(x - 0.5 * w, 0.0, std::max(0.0, width() - w));
        const bool overlaps = std::any_of(taken.begin(), taken.end(), [&](const auto& r) {
          return x0 < r.second + 6.0 && x0 + w + 6.0 > r.first;
        });
        if (overlaps) continue;
        taken.emplace_back(x0, x0 + w);
        p.drawLine(QPointF(x, area.bottom() - 3), QPointF(x, area.bottom() + 1));
        p.drawText(QPointF(x0, height() - 2), name);
      }
    }
  }
  QSlider::paintEvent(event);
}

}  // namespace vh::ui
