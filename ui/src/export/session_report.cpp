#include "vh/ui/export/session_report.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <future>
#include <memory>
#include <optional>
#include <stdexcept>
#include <tuple>

#include <QBuffer>
#include <QByteArray>
#include <QGraphicsScene>
#include <QGraphicsLayout>
#include <QImage>
#include <QPainter>
#include <QPen>
#include <QPolygonF>
#include <QtCharts/QChart>
#include <QtCharts/QLegendMarker>
#include <QtCharts/QLineSeries>
#include <QtCharts/QScatterSeries>
#include <QtCharts/QValueAxis>

#include <nlohmann/json.hpp>

#include "vh/haptics/scalar_volume.h"
#include "vh/io/private_files.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/anonymize.h"
#include "vh/runtime/session_metadata.h"
#include "vh/ui/export/report_format.h"
#include "report_drilling.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using runtime::MetricValue;
using runtime::Recording;
using runtime::SessionMetrics;
using runtime::TickRecord;

double norm3(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

/// `image` as a data: URI of a PNG.
std::string pngUri(const QImage& image) {
  QByteArray png;
  QBuffer buffer(&png);
  buffer.open(QIODevice::WriteOnly);
  if (!image.save(&buffer, "PNG")) throw std::runtime_error("a chart could not be encoded as PNG");
  return "data:image/png;base64," + png.toBase64().toStdString();
}

/// Renders `chart` (owned here) off screen and returns it as a data: URI of a PNG.
std::string chartImage(QChart* chart, int width, int height) {
  QGraphicsScene scene;
  scene.addItem(chart);  // the scene owns and deletes the chart
  chart->setAnimationOptions(QChart::NoAnimation);
  chart->setGeometry(0, 0, width, height);
  if (chart->layout() != nullptr) chart->layout()->activate();
  QImage image(width, height, QImage::Format_RGB32);
  image.fill(Qt::white);
  {
    QPainter painter(&image);
    painter.setRenderHint(QPainter::Antialiasing);
    scene.render(&painter, QRectF(0, 0, width, height), QRectF(0, 0, width, height));
  }
  return pngUri(image);
}

std::string imageTag(const std::string& uri, const std::string& alt, const char* cls = "chart") {
  return "<img class=\"" + std::string(cls) + "\" alt=\"" + escapeHtml(alt) + "\" src=\"" + uri + "\">\n";
}

QValueAxis* addAxis(QChart* chart, Qt::Alignment where, const QString& title, double lo, double hi) {
  auto* axis = new QValueAxis;
  axis->setTitleText(title);
  // A recording of non-finite values (damaged, or a solver that failed) still gets its axes:
  // Qt Charts refuses a NaN range and the page's pictures must survive it.
  if (!std::isfinite(lo)) lo = 0.0;
  if (!std::isfinite(hi) || !(hi > lo)) hi = lo + 1.0;
  axis->setRange(lo, hi);
  axis->setLabelFormat("%.4g");
  chart->addAxis(axis, where);
  return axis;
}

QLineSeries* lineSeries(const QString& name, const QColor& colour, qreal width = 1.5,
                        Qt::PenStyle style = Qt::SolidLine) {
  auto* s = new QLineSeries;
  s->setName(name);
  QPen pen(colour);
  pen.setWidthF(width);
  pen.setStyle(style);
  s->setPen(pen);
  return s;
}

/// Time series thinned to at most `buckets` points, each the largest value of its bucket (so
/// peaks survive), at the bucket's time of that value.
template <typename Value>
QList<QPointF> thinnedByMax(const std::vector<TickRecord>& records, std::size_t buckets, Value value) {
  QList<QPointF> out;
  const std::size_t n = records.size();
  const std::size_t per = std::max<std::size_t>(1, (n + buckets - 1) / buckets);
  for (std::size_t b = 0; b < n; b += per) {
    // Non-finite values and times are left out (a damaged or failed recording): no point drawn.
    std::size_t best = n;
    double best_v = 0.0;
    for (std::size_t i = b; i < std::min(n, b + per); ++i) {
      const double v = value(records[i]);
      if (!std::isfinite(v) || !std::isfinite(records[i].time_s)) continue;
      if (best == n || v > best_v) best_v = v, best = i;
    }
    if (best < n) out.append(QPointF(records[best].time_s, best_v));
  }
  return out;
}

/// The events worth a mark on the time charts: markers and critical contacts / removals.
bool markedEvent(const runtime::RecordingEvent& e) {
  return e.type == "marker" || e.type == "critical_removed" || e.type == "critical_contact" ||
         e.type == "proximity_alarm";
}

std::string forceChart(const Recording& rec, const SessionMetrics& m, const SessionReportOptions& o) {
  auto* chart = new QChart;
  chart->setTitle("Force and torque on the hand");
  const QList<QPointF> force = thinnedByMax(rec.records, 2000, [](const TickRecord& r) { return norm3(r.force_W_N); });
  const QList<QPointF> torque =
      thinnedByMax(rec.records, 2000, [](const TickRecord& r) { return norm3(r.torque_W_Nm); });
  const double t0 = rec.records.front().time_s, t1 = rec.records.back().time_s;
  QValueAxis* x = addAxis(chart, Qt::AlignBottom, "time [s]", t0, t1);
  x->applyNiceNumbers();
  double fmax = std::max(m.max_force_N, m.force_threshold_N) * 1.1;
  if (!std::isfinite(fmax)) fmax = 1.0;
  QValueAxis* yf = addAxis(chart, Qt::AlignLeft, "|F| [N]", 0.0, fmax > 0 ? fmax : 1.0);
  QValueAxis* yt = addAxis(chart, Qt::AlignRight, "|torque| [N*m]", 0.0, m.max_torque_Nm > 0 ? m.max_torque_Nm * 1.1 : 1.0);
  yf->applyNiceNumbers();
  yt->applyNiceNumbers();
  QLineSeries* f = lineSeries("|F| [N]", QColor(0x1f, 0x77, 0xb4));
  f->replace(force);
  QLineSeries* t = lineSeries("|torque| [N*m]", QColor(0xff, 0x7f, 0x0e), 1.0);
  t->replace(torque);
  QLineSeries* thr = lineSeries(QString::fromStdString("threshold " + formatQuantity(m.force_threshold_N, "N")),
                                QColor(0xd6, 0x27, 0x28), 1.0,
                                Qt::DashLine);
  thr->append(t0, m.force_threshold_N);
  thr->append(t1, m.force_threshold_N);
  for (QLineSeries* s : {f, thr}) {
    chart->addSeries(s);
    s->attachAxis(x);
    s->attachAxis(yf);
  }
  chart->addSeries(t);
  t->attachAxis(x);
  t->attachAxis(yt);
  // Events: a mark at the top of the force axis at each time.
  auto* marks = new QScatterSeries;
  marks->setName("markers and critical events");
  marks->setMarkerShape(QScatterSeries::MarkerShapeRectangle);
  marks->setMarkerSize(9);
  marks->setColor(QColor(0x2c, 0xa0, 0x2c));
  for (const auto& e : rec.events)
    if (markedEvent(e) && std::isfinite(e.time_s)) marks->append(e.time_s, fmax * 0.97);
  chart->addSeries(marks);
  marks->attachAxis(x);
  marks->attachAxis(yf);
  return chartImage(chart, o.chart_width, o.chart_height);
}

std::string speedChart(const Recording& rec, const SessionMetrics& m, const SessionReportOptions& o) {
  auto* chart = new QChart;
  chart->setTitle("Speed of the device (the hand)");
  chart->legend()->hide();
  const std::vector<TickRecord>& r = rec.records;
  // A placement (Touch the Surface, Home, Reset Device) moved the tools, not the hand: the line
  // breaks there (runtime::deviceSpeedSeries(), as the metrics leave it out) and each is marked
  // on the time axis.
  const runtime::DeviceSpeedSeries series =
      runtime::deviceSpeedSeries(rec, m.servo_rate_Hz, o.metrics.derivative_step_s, std::max<std::size_t>(1, r.size() / 2000));
  QList<QPointF> placements;
  for (const double t_s : series.placements_s) placements.append(QPointF(t_s, 0.0));
  const double vmax = series.max_m_per_s;
  QValueAxis* x = addAxis(chart, Qt::AlignBottom, "time [s]", r.front().time_s, r.back().time_s);
  x->applyNiceNumbers();
  QValueAxis* y = addAxis(chart, Qt::AlignLeft, "speed [m/s]", 0.0, vmax > 0 ? vmax * 1.1 : 1.0);
  y->applyNiceNumbers();
  for (const auto& piece : series.pieces) {
    QList<QPointF> points;
    for (const auto& [t_s, v] : piece) points.append(QPointF(t_s, v));
    QLineSeries* s = lineSeries("speed", QColor(0x94, 0x67, 0xbd));
    s->replace(points);
    chart->addSeries(s);
    s->attachAxis(x);
    s->attachAxis(y);
  }
  if (!placements.isEmpty()) {
    auto* marks = new QScatterSeries;
    marks->setName("placement (the tools moved, not the hand)");
    marks->setMarkerShape(QScatterSeries::MarkerShapeTriangle);
    marks->setMarkerSize(9.0);
    marks->setColor(QColor(0x7f, 0x7f, 0x7f));
    marks->replace(placements);
    chart->addSeries(marks);
    marks->attachAxis(x);
    marks->attachAxis(y);
    chart->legend()->show();
    for (QLegendMarker* m : chart->legend()->markers())
      if (m->series() != marks) m->setVisible(false);
  }
  return chartImage(chart, o.chart_width, o.chart_height * 3 / 4);
}

/// The nearest critical segment's distance over time [mm] (clipped at the 20 mm range) with the
/// warning and alarm distances of the nearest critical segment as dashed lines.
std::string proximityChart(const Recording& rec, const SessionMetrics& m, const SessionReportOptions& o) {
  auto* chart = new QChart;
  chart->setTitle("Distance to the nearest critical segment");
  const double range_mm = 1e3 * runtime::kProximityRange_m;
  // Thinned by the smallest distance of each bucket (the approaches survive): max of minus it.
  const QList<QPointF> neg = thinnedByMax(rec.records, 2000, [range_mm](const TickRecord& r) {
    return -std::min(range_mm, std::isfinite(r.critical_distance_m) ? 1e3 * r.critical_distance_m : range_mm);
  });
  QList<QPointF> d;
  double top_mm = 2.0 * 1e3 * m.proximity.front().thresholds.warn_m;  // at least twice the warning
  for (const QPointF& p : neg) {
    d.append(QPointF(p.x(), -p.y()));
    top_mm = std::max(top_mm, std::min(range_mm, -p.y() * 1.1));
  }
  const double t0 = rec.records.front().time_s, t1 = rec.records.back().time_s;
  QValueAxis* x = addAxis(chart, Qt::AlignBottom, "time [s]", t0, t1);
  x->applyNiceNumbers();
  QValueAxis* y = addAxis(chart, Qt::AlignLeft, "distance [mm]", 0.0, top_mm);
  y->applyNiceNumbers();
  QLineSeries* s = lineSeries("nearest critical segment [mm]", QColor(0x1f, 0x77, 0xb4));
  s->replace(d);
  std::vector<QLineSeries*> all{s};
  const runtime::SegmentProximityStats& first = m.proximity.front();  // thresholds of the first
  for (const auto& [value_m, name, colour] : {std::tuple{first.thresholds.warn_m, "warn", QColor(0xff, 0x7f, 0x0e)},
                                               std::tuple{first.thresholds.alarm_m, "alarm", QColor(0xd6, 0x27, 0x28)}}) {
    QLineSeries* l = lineSeries(QString::fromStdString(std::string(name) + " " + formatQuantity(1e3 * value_m, "mm")),
                                colour, 1.0, Qt::DashLine);
    l->append(t0, 1e3 * value_m);
    l->append(t1, 1e3 * value_m);
    all.push_back(l);
  }
  for (QLineSeries* l : all) {
    chart->addSeries(l);
    l->attachAxis(x);
    l->attachAxis(y);
  }
  return chartImage(chart, o.chart_width, o.chart_height);
}

/// Per critical segment: time within each threshold, entries, the closest approach.
std::string proximityTable(const SessionMetrics& m) {
  std::string html =
      "<table>\n<tr><th>critical segment</th><th>warn / alarm</th><th>time within warn</th><th>time within alarm"
      "</th><th>entries (warn / alarm)</th><th>closest approach</th><th>at</th></tr>\n";
  for (const auto& p : m.proximity) {
    const bool near = std::isfinite(p.closest_m);
    html += "<tr" + std::string(p.time_within_alarm_s > 0 ? " class=\"critical\"" : "") + "><td>" + escapeHtml(p.name) +
            "</td><td class=\"n\">" + formatNumber(1e3 * p.thresholds.warn_m) + " / " +
            formatQuantity(1e3 * p.thresholds.alarm_m, "mm") + "</td><td class=\"n\">" +
            formatQuantity(p.time_within_warn_s, "s") + "</td><td class=\"n\">" +
            formatQuantity(p.time_within_alarm_s, "s") + "</td><td class=\"n\">" +
            formatNumber(static_cast<double>(p.warnings)) + " / " + formatNumber(static_cast<double>(p.alarms)) +
            "</td><td class=\"n\">" + (near ? formatQuantity(1e3 * p.closest_m, "mm") : std::string("beyond 20 mm")) +
            "</td><td class=\"n\">" + (near ? formatClock(p.closest_time_s) : std::string("-")) + "</td></tr>\n";
  }
  return html + "</table>\n";
}

/// The "Proximity" section: the table and the distance over time, or why there is none.
std::string proximitySection(const Recording& rec, const SessionMetrics& m, const SessionReportOptions& o) {
  if (m.proximity.empty()) return "<p>The recording names no critical segment, so no distances to one.</p>\n";
  if (std::isnan(m.proximity.front().closest_m))
    return "<p>This recording (format version " + std::to_string(rec.version) +
           ") predates the distance to critical segments: record again to see it.</p>\n";
  std::string html = "<p class=\"small\">From the proxy's point shell to each critical segment's voxel centres, "
                     "within half a voxel diagonal; each tick records the nearest critical segment.</p>\n" +
                     proximityTable(m);
  if (!rec.records.empty()) html += imageTag(proximityChart(rec, m, o), "distance to the nearest critical segment over time");
  return html;
}

// ---- Contact maps and path maps: projections in the patient's frame ------------------------------

/// The patient-frame letter of a W axis direction: W is LPS (+x the patient's left, +y
/// posterior, +z superior).
std::string directionLetter(const Eigen::Vector3d& d_W) {
  int a = 0;
  d_W.cwiseAbs().maxCoeff(&a);
  static const char* kPlus[] = {"L", "P", "S"};
  static const char* kMinus[] = {"R", "A", "I"};
  return d_W[a] > 0 ? kPlus[a] : kMinus[a];
}

/// Where a viewer on the side of `letter` stands, in words.
std::string sideWords(const std::string& letter) {
  if (letter == "L") return "the patient's left (L)";
  if (letter == "R") return "the patient's right (R)";
  if (letter == "A") return "the front (anterior, A)";
  if (letter == "P") return "behind (posterior, P)";
  if (letter == "S") return "above the head (superior, S)";
  return "below the feet (inferior, I)";
}

/// One projection of the scene frame W onto a picture: rightward `right_W`, upward `up_W`,
/// toward the viewer `out_W` (unit W axes, right = up x out: a view, never a mirror image).
struct MapView {
  std::string name;  ///< "Axial", "Coronal", "Sagittal".
  Eigen::Vector3d right_W, up_W, out_W;
  int depth_axis = 2;  ///< The W axis along out_W.

  QPointF project_mm(const double p_W_m[3]) const {
    const Eigen::Vector3d p(p_W_m[0], p_W_m[1], p_W_m[2]);
    return QPointF(p.dot(right_W) * 1e3, p.dot(up_W) * 1e3);
  }
  /// "Axial, seen from above the head (superior, S): A at the top, R on the right".
  std::string caption() const {
    return name + ", seen from " + sideWords(directionLetter(out_W)) + ": " + directionLetter(up_W) + " at the top, " +
           directionLetter(-up_W) + " at the bottom, " + directionLetter(-right_W) + " on the left, " +
           directionLetter(right_W) + " on the right";
  }
};

/// The three views, each from the side the tool was on: the side the force on the hand pointed
/// to, summed over the ticks in contact along the view's axis (the force pushes the hand out of
/// the surface, toward the tool), where that sum is at least a quarter of the summed |F|.
/// Otherwise the usual radiological sides: axial from below,
/// coronal from the front, sagittal from the left. Anterior is up on the axial view, superior
/// on the others.
std::array<MapView, 3> mapViews(const Recording& rec) {
  Eigen::Vector3d force_sum_W = Eigen::Vector3d::Zero();
  double magnitude_sum_N = 0.0;
  for (const TickRecord& r : rec.records) {
    if (r.contacts == 0) continue;
    const Eigen::Vector3d f(r.force_W_N[0], r.force_W_N[1], r.force_W_N[2]);
    force_sum_W += f;
    magnitude_sum_N += f.norm();
  }
  // A side only where the force pointed along the axis for a fair part (a quarter) of its size:
  // a press on the top of the head says nothing about front or back.
  const auto side = [&](int axis, double otherwise) {
    const double along = force_sum_W[axis], enough = std::max(0.25 * magnitude_sum_N, 1e-9);
    return along > enough ? 1.0 : along < -enough ? -1.0 : otherwise;
  };
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(), z = Eigen::Vector3d::UnitZ();
  std::array<MapView, 3> views;
  views[0] = {"Axial", {}, -y, side(2, -1.0) * z, 2};
  views[1] = {"Coronal", {}, z, side(1, -1.0) * y, 1};
  views[2] = {"Sagittal", {}, z, side(0, 1.0) * x, 0};
  for (MapView& v : views) v.right_W = v.up_W.cross(v.out_W);
  return views;
}

/// The square a map shows [mm, picture coordinates]: centred on the points' bounding box, at
/// least kMinField_mm across (the anatomy around the contacts, not a few millimetres of it),
/// larger when the points spread wider.
struct MapFrame {
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  double width_mm() const { return x1 - x0; }
};
constexpr double kMinField_mm = 80.0;

MapFrame frameAround(const QList<QPointF>& pts) {
  double ax = 1e300, bx = -1e300, ay = 1e300, by = -1e300;
  for (const QPointF& p : pts)
    ax = std::min(ax, p.x()), bx = std::max(bx, p.x()), ay = std::min(ay, p.y()), by = std::max(by, p.y());
  if (pts.isEmpty()) ax = bx = ay = by = 0.0;
  const double half = std::max(std::max(bx - ax, by - ay) / 2 * 1.15, kMinField_mm / 2);
  const double cx = (ax + bx) / 2, cy = (ay + by) / 2;
  return {cx - half, cx + half, cy - half, cy + half};
}

/// The felt surface of the recorded scene, for the maps' background.
struct Anatomy {
  std::shared_ptr<const haptics::ScalarVolume> field;  ///< The felt field, in W [m].
  double isovalue = 0.0;                               ///< Its surface's level.
};

/// The felt surface as the viewer of `view` sees it over `frame`, `pixels` square: each pixel's
/// ray goes from the viewer's side of the volume along -out (steps of a voxel, at most 400 per
/// ray) to its first point inside the surface, refined by bisection, and is lit by a light
/// above-left of the viewer (Lambert on the field's gradient), dimmed with depth; transparent
/// where it meets nothing. Row 0 is the top.
QImage anatomyProjection(const Anatomy& anatomy, const MapView& view, const MapFrame& frame, int pixels) {
  const int c = view.depth_axis;
  const haptics::ScalarVolume& f = *anatomy.field;
  const Eigen::Vector3d lo = f.boundsMin_W_m(), hi = f.boundsMax_W_m();
  const double depth_m = std::max(hi[c] - lo[c], 1e-9);
  const double step = std::max(f.geometry().minSpacing(), depth_m / 400.0);
  const double toward = view.out_W[c] > 0 ? 1.0 : -1.0;  // the viewer at hi[c] (+1) or lo[c] (-1)
  const Eigen::Vector3d light_W = (view.out_W + 0.45 * view.up_W - 0.35 * view.right_W).normalized();
  QImage image(pixels, pixels, QImage::Format_ARGB32);
  image.fill(Qt::transparent);
  for (int row = 0; row < pixels; ++row) {
    for (int col = 0; col < pixels; ++col) {
      const double u_m = (frame.x0 + frame.width_mm() * (col + 0.5) / pixels) * 1e-3;
      const double v_m = (frame.y1 - (frame.y1 - frame.y0) * (row + 0.5) / pixels) * 1e-3;
      Eigen::Vector3d p = u_m * view.right_W + v_m * view.up_W;
      bool outside_box = false;
      for (int a = 0; a < 3; ++a) outside_box |= a != c && (p[a] < lo[a] || p[a] > hi[a]);
      if (outside_box) continue;
      const double start = toward > 0 ? hi[c] : lo[c];
      for (double d = 0.0; d <= depth_m; d += step) {
        p[c] = start - toward * d;
        if (!f.isInside(p, anatomy.isovalue)) continue;
        double out_d = std::max(0.0, d - step), in_d = d;  // bisection between outside and inside
        for (int k = 0; k < 5 && d > 0.0; ++k) {
          const double mid = 0.5 * (out_d + in_d);
          p[c] = start - toward * mid;
          (f.isInside(p, anatomy.isovalue) ? in_d : out_d) = mid;
        }
        p[c] = start - toward * in_d;
        // The normal from the gradient averaged over a voxel around the hit: the trilinear
        // field's own gradient jumps at every slice and would draw the slices as rings.
        Eigen::Vector3d g = f.gradient(p);
        const double r = f.geometry().minSpacing();
        for (const Eigen::Vector3d& e : {view.right_W, view.up_W, view.out_W}) g += f.gradient(p + r * e) + f.gradient(p - r * e);
        // Inside is above the isovalue: the outward normal is down the gradient.
        const double lambert = g.norm() > 0 ? std::max(0.0, -g.normalized().dot(light_W)) : 0.6;
        const double dim = 1.0 - 0.35 * in_d / depth_m;
        const double shade = (0.28 + 0.72 * lambert) * dim;
        image.setPixelColor(col, row, QColor::fromRgbF(std::min(1.0, 0.96 * shade), std::min(1.0, 0.92 * shade),
                                                       std::min(1.0, 0.84 * shade)));
        break;
      }
    }
  }
  return image;
}

/// One layer of a map: points or a line, with its legend name.
struct MapLayer {
  QString name;
  QColor colour;
  QList<QPointF> points_mm;  ///< Picture coordinates (MapView::project_mm).
  bool line = false;
  Qt::PenStyle style = Qt::SolidLine;
};

/// The largest of 5, 10, 20, 50, 100, 200 mm that is at most a quarter of `field_mm`.
double scaleBar_mm(double field_mm) {
  double best = 5.0;
  for (double l : {5.0, 10.0, 20.0, 50.0, 100.0, 200.0})
    if (l <= field_mm / 4) best = l;
  return best;
}

/// The map's layers in the square field `plot` (`side` pixels) showing `frame`: lines as
/// polylines, points as dots, clipped to the field.
void drawMapLayers(QPainter& painter, const QRectF& plot, int side, const MapFrame& frame,
                   const std::vector<MapLayer>& layers) {
  const auto toPixel = [&](const QPointF& p) {
    return QPointF(plot.left() + (p.x() - frame.x0) / frame.width_mm() * side,
                   plot.top() + (frame.y1 - p.y()) / (frame.y1 - frame.y0) * side);
  };
  painter.setClipRect(plot);
  for (const MapLayer& layer : layers) {
    if (layer.line) {
      QPen pen(layer.colour, 2.0, layer.style);
      painter.setPen(pen);
      QPolygonF poly;
      for (const QPointF& p : layer.points_mm) poly << toPixel(p);
      painter.drawPolyline(poly);
    } else {
      painter.setPen(QPen(layer.colour.darker(150), 0.8));
      painter.setBrush(layer.colour);
      for (const QPointF& p : layer.points_mm) painter.drawEllipse(toPixel(p), 2.6, 2.6);
    }
  }
}

/// The patient-frame letters of `view`, in boxes at the middle of each side of `plot` (`font`
/// becomes 16 px).
void drawFrameLetters(QPainter& painter, QFont& font, const QRectF& plot, const MapView& view) {
  font.setPixelSize(16);
  painter.setFont(font);
  const auto letterBox = [&](const QPointF& centre, const std::string& letter) {
    const QRectF box(centre.x() - 12, centre.y() - 12, 24, 24);
    painter.setPen(Qt::NoPen);
    painter.setBrush(QColor(255, 255, 255, 220));
    painter.drawRoundedRect(box, 4, 4);
    painter.setPen(QColor(0x10, 0x10, 0x10));
    painter.drawText(box, Qt::AlignCenter, QString::fromStdString(letter));
  };
  letterBox(QPointF(plot.center().x(), plot.top() + 16), directionLetter(view.up_W));
  letterBox(QPointF(plot.center().x(), plot.bottom() - 16), directionLetter(-view.up_W));
  letterBox(QPointF(plot.left() + 16, plot.center().y()), directionLetter(-view.right_W));
  letterBox(QPointF(plot.right() - 16, plot.center().y()), directionLetter(view.right_W));
}

/// The scale bar, bottom left in `plot` (`side` pixels for the frame's width; `font` becomes
/// 12 px, not bold).
void drawScaleBar(QPainter& painter, QFont& font, const QRectF& plot, int side, const MapFrame& frame) {
  const double bar_mm = scaleBar_mm(frame.width_mm());
  const double bar_px = bar_mm / frame.width_mm() * side;
  const QRectF bar_box(plot.left() + 8, plot.bottom() - 40, bar_px + 16, 32);
  painter.setPen(Qt::NoPen);
  painter.setBrush(QColor(255, 255, 255, 220));
  painter.drawRoundedRect(bar_box, 4, 4);
  painter.setBrush(QColor(0x10, 0x10, 0x10));
  painter.drawRect(QRectF(bar_box.left() + 8, bar_box.bottom() - 10, bar_px, 4));
  font.setPixelSize(12);
  font.setBold(false);
  painter.setFont(font);
  painter.setPen(QColor(0x10, 0x10, 0x10));
  painter.drawText(QRectF(bar_box.left(), bar_box.top() + 2, bar_box.width(), 16), Qt::AlignCenter,
                   QString::fromStdString(formatNumber(bar_mm) + " mm"));
}

/// The legend below `plot`: two columns of the layers' marks and names.
void drawMapLegend(QPainter& painter, const QRectF& plot, int side, const std::vector<MapLayer>& layers,
                   int margin, int legend_row) {
  const double legend_top = plot.bottom() + margin;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const double x = margin + (i % 2) * side / 2.0, y = legend_top + (i / 2) * legend_row + legend_row / 2.0;
    if (layers[i].line) {
      painter.setPen(QPen(layers[i].colour, 2.0, layers[i].style));
      painter.drawLine(QPointF(x + 2, y), QPointF(x + 22, y));
    } else {
      painter.setPen(QPen(layers[i].colour.darker(150), 0.8));
      painter.setBrush(layers[i].colour);
      painter.drawEllipse(QPointF(x + 12, y), 5, 5);
    }
    painter.setPen(QColor(0x22, 0x22, 0x22));
    painter.drawText(QRectF(x + 28, y - legend_row / 2.0, side / 2.0 - 30, legend_row), Qt::AlignVCenter | Qt::AlignLeft,
                     layers[i].name);
  }
}

/// A map as a PNG data: URI, `size` pixels wide: the title, the square field (`frame`) with the
/// anatomy behind the layers, the patient-frame letters at its four sides, a scale bar, and the
/// legend below. The alt text and caption say the same in words.
std::string mapImage(const QString& title, const MapView& view, const MapFrame& frame,
                     const std::vector<MapLayer>& layers, int size, const Anatomy* anatomy) {
  constexpr int kTitle = 30, kMargin = 10, kLegendRow = 22;
  const int side = size - 2 * kMargin;
  const int legend_rows = (static_cast<int>(layers.size()) + 1) / 2;
  QImage image(size, kTitle + side + kMargin + legend_rows * kLegendRow + kMargin, QImage::Format_RGB32);
  image.fill(Qt::white);
  QPainter painter(&image);
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setRenderHint(QPainter::SmoothPixmapTransform);
  QFont font = painter.font();
  font.setPixelSize(14);
  font.setBold(true);
  painter.setFont(font);
  painter.setPen(QColor(0x22, 0x22, 0x22));
  painter.drawText(QRect(0, 0, size, kTitle), Qt::AlignCenter, title);
  const QRectF plot(kMargin, kTitle, side, side);
  painter.fillRect(plot, QColor(0x3a, 0x3f, 0x47));  // dark behind the surface, as a CT viewer
  if (anatomy != nullptr) painter.drawImage(plot, anatomyProjection(*anatomy, view, frame, std::min(side, 240)));
  drawMapLayers(painter, plot, side, frame, layers);
  painter.setClipping(false);
  painter.setBrush(Qt::NoBrush);
  painter.setPen(QPen(QColor(0x88, 0x88, 0x88), 1.0));
  painter.drawRect(plot);
  drawFrameLetters(painter, font, plot, view);
  drawScaleBar(painter, font, plot, side, frame);
  drawMapLegend(painter, plot, side, layers, kMargin, kLegendRow);
  painter.end();
  return pngUri(image);
}

/// A map with its caption: the view in words, the field's width and the scale bar.
std::string mapFigure(const std::string& uri, const std::string& title, const MapView& view, const MapFrame& frame,
                      int width_px) {
  const std::string words = view.caption() + ". Field " + formatNumber(frame.width_mm(), 2) + " mm across, scale bar " +
                            formatNumber(scaleBar_mm(frame.width_mm())) + " mm.";
  return "<figure class=\"map\" style=\"width: " + std::to_string(width_px) + "px\">" +
         imageTag(uri, title + ". " + words, "map") + "<figcaption>" + escapeHtml(words) + "</figcaption></figure>\n";
}

/// The contact map: proxy positions in contact on the three views, in four force bands.
std::string contactMap(const Recording& rec, const SessionMetrics& m, const SessionReportOptions& o,
                       const Anatomy* anatomy) {
  std::vector<const TickRecord*> contacts;
  // Contacts with a non-finite force or pose (a damaged or failed recording) are not drawn.
  for (const TickRecord& r : rec.records)
    if (r.contacts > 0 && std::isfinite(norm3(r.force_W_N)) && std::isfinite(norm3(r.p_WP_m))) contacts.push_back(&r);
  if (contacts.empty()) return "<p>The tool touched nothing: no contact map.</p>\n";
  const std::size_t stride = std::max<std::size_t>(1, contacts.size() / 3000);
  const double fmax = std::isfinite(m.max_force_N) ? std::max(m.max_force_N, 1e-9) : 1.0;
  static const QColor kBand[] = {QColor(0x31, 0x82, 0xbd), QColor(0x31, 0xa3, 0x54), QColor(0xfd, 0x8d, 0x3c),
                                 QColor(0xde, 0x2d, 0x26)};
  std::string html = "<div class=\"maps\">\n";
  for (const MapView& view : mapViews(rec)) {
    std::vector<MapLayer> layers(4);
    for (int band = 0; band < 4; ++band) {
      layers[band].name = QString::fromStdString("|F| " + formatRange(fmax * band / 4, fmax * (band + 1) / 4, "N", 2));
      layers[band].colour = kBand[band];
    }
    QList<QPointF> all;
    for (std::size_t i = 0; i < contacts.size(); i += stride) {
      const double f = norm3(contacts[i]->force_W_N);
      const int band = std::clamp(static_cast<int>(std::min(4.0, f / fmax * 4.0)), 0, 3);
      const QPointF p = view.project_mm(contacts[i]->p_WP_m);
      layers[static_cast<std::size_t>(band)].points_mm.append(p);
      all.append(p);
    }
    const MapFrame frame = frameAround(all);
    const std::string title = "Contacts, " + view.name;
    html += mapFigure(mapImage(QString::fromStdString(title), view, frame, layers, o.map_size, anatomy), title, view, frame,
                      o.map_size);
  }
  return html + "</div>\n";
}

std::string pathsMap(const runtime::ReferenceComparison& c, const MapView& view, int size, const Anatomy* anatomy) {
  std::vector<MapLayer> layers(2);
  layers[0] = {"this session", QColor(0x1f, 0x77, 0xb4), {}, true, Qt::SolidLine};
  layers[1] = {"reference", QColor(0xff, 0x7f, 0x0e), {}, true, Qt::DashLine};
  QList<QPointF> all;
  for (const auto& p : c.session_path) layers[0].points_mm.append(view.project_mm(p.data()));
  for (const auto& p : c.reference_path) layers[1].points_mm.append(view.project_mm(p.data()));
  all = layers[0].points_mm + layers[1].points_mm;
  const MapFrame frame = frameAround(all);
  const std::string title = "Device paths, " + view.name;
  return mapFigure(mapImage(QString::fromStdString(title), view, frame, layers, size, anatomy), title, view, frame, size);
}

std::string metricsTable(const std::vector<MetricValue>& values) {
  std::string html = "<table>\n<tr><th>metric</th><th>value</th><th>column in the cohort table</th></tr>\n";
  for (const MetricValue& v : values)
    html += "<tr><td>" + escapeHtml(v.label) + "</td><td class=\"n\">" + escapeHtml(formatQuantity(v.value, v.unit)) +
            "</td><td class=\"small\"><code>" + v.key + "</code></td></tr>\n";
  return html + "</table>\n";
}

/// The figures a teacher reads first, from the metrics (the full table is further down).
std::string summaryTable(const std::vector<MetricValue>& values) {
  static const char* kKeys[] = {"duration_s", "time_in_contact_s", "mean_contact_force_N", "max_force_N",
                                "time_above_threshold_s", "critical_touches", "cavity_at_start_mm3", "removed_mm3",
                                "cavity_mm3", "critical_removed_mm3", "technique_force_events", "technique_speed_events",
                                "technique_shaft_events"};
  // The drilling rows only for a session that drilled or began on a cavity.
  bool drilling = false;
  for (const MetricValue& v : values)
    drilling = drilling || ((v.key == "drill_on_s" || v.key == "cavity_mm3") && v.value > 0.0);
  const auto drillingRow = [](const std::string& key) {
    return key == "cavity_at_start_mm3" || key == "removed_mm3" || key == "cavity_mm3";
  };
  std::string cells;
  for (const char* key : kKeys)
    for (const MetricValue& v : values)
      if (v.key == key && (drilling || !drillingRow(v.key)))
        cells += "<tr><th>" + escapeHtml(v.label) + "</th><td class=\"n\">" + escapeHtml(formatQuantity(v.value, v.unit)) +
                 "</td></tr>\n";
  return "<h2>Summary</h2>\n<table class=\"meta\">\n" + cells + "</table>\n";
}

std::string segmentsTable(const SessionMetrics& m) {
  if (m.segments.empty())
    return "<p>The recording names no segments (no segmentation was open), so no time per segment.</p>\n";
  std::string html =
      "<table>\n<tr><th>segment</th><th>critical</th><th>time in contact</th><th>touches</th>"
      "<th>peak |F|</th><th>drilled away</th></tr>\n";
  for (const auto& s : m.segments)
    html += "<tr" + std::string(s.critical ? " class=\"critical\"" : "") + "><td>" + escapeHtml(s.name) + "</td><td>" +
            (s.critical ? "yes" : "no") + "</td><td class=\"n\">" + formatQuantity(s.time_in_contact_s, "s") +
            "</td><td class=\"n\">" + formatNumber(static_cast<double>(s.touches)) + "</td><td class=\"n\">" +
            formatQuantity(s.peak_force_N, "N") + "</td><td class=\"n\">" + formatQuantity(s.removed_mm3, "mm^3") + " (" +
            formatNumber(static_cast<double>(s.removed_voxels)) + " voxels)</td></tr>\n";
  return html + "</table>\n";
}

/// The scan's value unit from the recording's metadata ("HU", "SUV"; empty when not named).
std::string valueUnitOf(const Recording& rec) {
  const nlohmann::json meta = nlohmann::json::parse(rec.metadata_json, nullptr, false);
  if (meta.is_object() && meta.contains("dataset") && meta["dataset"].is_object())
    return meta["dataset"].value("value_unit", std::string{});
  return {};
}

std::string eventsTable(const Recording& rec) {
  if (rec.events.empty()) return "<p>No events were recorded.</p>\n";
  const std::vector<EventRow> rows = summariseEvents(rec.events, valueUnitOf(rec));
  std::string html = "<table class=\"events\">\n<tr><th>time [m:ss.s]</th><th>event</th></tr>\n";
  for (const EventRow& r : rows) {
    std::string text = escapeHtml(r.text);
    if (r.count > 1)
      text += " <span class=\"small\">(first at " + formatClock(r.first_s) + ", last at " + formatClock(r.last_s) +
              ")</span>";
    html += "<tr" + std::string(r.critical ? " class=\"critical\"" : "") + "><td class=\"n\">" + formatClock(r.first_s) +
            "</td><td>" + text + "</td></tr>\n";
  }
  html += "</table>\n";
  if (rows.size() < rec.events.size())
    html += "<p class=\"small\">" + std::to_string(rec.events.size()) + " events in " + std::to_string(rows.size()) +
            (rows.size() == 1 ? " row" : " rows") +
            ": a kind repeated more than 5 times is one row; <code>volume-haptics export --events-csv</code> "
            "lists every event.</p>\n";
  return html;
}

/// A signed difference with its unit ("+1.2 N", "-350 ms", "0").
std::string signedQuantity(double v, const std::string& unit) {
  const std::string text = formatQuantity(v, unit);
  return v > 0 && std::isfinite(v) ? "+" + text : text;
}

std::string comparisonSection(const runtime::ReferenceComparison& c, const std::string& reference_title,
                              const std::array<MapView, 3>& views, const SessionReportOptions& o, const Anatomy* anatomy) {
  std::string html = "<h2>Against the reference " + escapeHtml(reference_title) + "</h2>\n";
  html += "<p>Mean distance between the two device paths after aligning them in time by dynamic time "
          "warping (Sakoe &amp; Chiba 1978), each thinned to " +
          std::to_string(c.path_samples) + " points: <b>" + formatQuantity(c.alignment.mean_distance_m, "m") +
          "</b> (" + std::to_string(c.alignment.path.size()) +
          " aligned pairs). Both recordings are in the same scene frame, so the paths are compared "
          "without moving either.</p>\n";
  html += "<table>\n<tr><th>metric</th><th>this session</th><th>reference</th><th>difference</th></tr>\n";
  for (std::size_t i = 0; i < c.session.size() && i < c.reference.size(); ++i)
    html += "<tr><td>" + escapeHtml(c.session[i].label) + "</td><td class=\"n\">" +
            escapeHtml(formatQuantity(c.session[i].value, c.session[i].unit)) + "</td><td class=\"n\">" +
            escapeHtml(formatQuantity(c.reference[i].value, c.reference[i].unit)) + "</td><td class=\"n\">" +
            escapeHtml(signedQuantity(c.session[i].value - c.reference[i].value, c.session[i].unit)) + "</td></tr>\n";
  html += "</table>\n";
  html += "<div class=\"maps\">\n" + pathsMap(c, views[0], o.map_size + 80, anatomy) +
          pathsMap(c, views[1], o.map_size + 80, anatomy) + "</div>\n";
  return html;
}

std::string metadataLine(const Recording& rec, const SessionMetrics& m) {
  const nlohmann::json meta = nlohmann::json::parse(rec.metadata_json, nullptr, false);
  std::string device;
  if (meta.is_object() && meta.contains("device") && meta["device"].is_object())
    device = meta["device"].value("name", std::string{}) + " (" + meta["device"].value("kind", std::string{}) + ")";
  std::string html = "<table class=\"meta\">\n";
  const auto row = [&](const char* k, const std::string& v) {
    if (!v.empty()) html += "<tr><th>" + std::string(k) + "</th><td>" + escapeHtml(v) + "</td></tr>\n";
  };
  row("scene", m.scene);
  row("dataset SHA-256", m.dataset_sha256);
  row("user / note", m.label);
  row("started (UTC)", m.start_time_utc);
  row("device", device);
  row("servo rate", formatNumber(m.servo_rate_Hz) + " Hz");
  return html + "</table>\n";
}

/// The recorded scene reloaded from the metadata once, for two things: its felt surface (its
/// scan, or its felt segments), set into `anatomy` as soon as it is loaded (null with `why` set
/// when it cannot be: a missing or changed dataset); then, with `replay_drilling`, the recording
/// replayed on it for what its burr removed per material (runtime::drillReportOfRecording()).
detail::DrilledByMaterial reloadScene(const Recording& rec, bool replay_drilling, std::string& why,
                                      std::promise<std::unique_ptr<Anatomy>>& anatomy) {
  detail::DrilledByMaterial drilled;
  std::optional<runtime::LoadedScene> scene;
  try {
    scene.emplace(runtime::loadRecordedScene(rec.metadata_json));
    auto loaded = std::make_unique<Anatomy>();
    loaded->field = scene->hapticField();
    loaded->isovalue = scene->hapticIsovalue();
    if (loaded->field == nullptr || loaded->field->empty()) throw std::runtime_error("the scene has no volume");
    anatomy.set_value(std::move(loaded));
  } catch (const std::exception& e) {
    why = e.what();
    if (replay_drilling) drilled.why = "the scene could not be reloaded (" + why + ")";
    anatomy.set_value(nullptr);
    return drilled;
  }
  return replay_drilling ? runtime::drillReportOfRecording(*scene, rec) : drilled;
}

/// --anonymize: anonymized copies of the recording and the reference (runtime::anonymizeRecording());
/// empty when not asked for.
struct Anonymized {
  Anonymized(bool anonymize, const Recording& original, const Recording* original_reference) {
    if (!anonymize) return;
    recording = std::make_unique<Recording>(original);
    ids = runtime::anonymizeRecording(*recording);
    if (original_reference != nullptr) {
      reference = std::make_unique<Recording>(*original_reference);
      runtime::anonymizeRecording(*reference);
    }
  }
  std::unique_ptr<Recording> recording;
  std::unique_ptr<Recording> reference;
  std::vector<std::string> ids;  ///< What was removed, to scrub other text with.
};

constexpr const char* kStyle = R"(<style>
body { font-family: sans-serif; margin: 2em; color: #222; max-width: 1160px; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid #ddd; padding: 2px 8px; text-align: left; }
td.n { text-align: right; font-variant-numeric: tabular-nums; } tr.critical td { background: #fde0dc; }
table.meta th { background: #f4f4f4; } .notice { background: #fff3cd; border: 1px solid #e0b000; padding: 0.6em 1em; }
img.chart { display: block; max-width: 100%; } .maps { display: flex; flex-wrap: wrap; gap: 8px; }
.small { color: #666; font-size: 0.9em; } figure.map { margin: 0; }
figure.map figcaption { font-size: 0.85em; color: #444; margin-top: 2px; } img.map { display: block; max-width: 100%; }
</style>
)";

}  // namespace

std::string sessionReportHtml(const Recording& original, const std::string& title_given,
                              const SessionReportOptions& options, const Recording* reference_given,
                              const std::string& reference_title_given) {
  if (options.chart_width < 64 || options.chart_height < 64 || options.map_size < 64)
    throw std::invalid_argument("report charts must be at least 64 pixels wide and high");
  // The scan is reloaded on a second thread while the metrics and the time charts are drawn.
  // With drilling, the same reloaded scene then replays the recording for the removal per
  // material.
  std::string why;
  std::promise<std::unique_ptr<Anatomy>> anatomy_promise;
  std::future<std::unique_ptr<Anatomy>> anatomy_loading;
  std::future<detail::DrilledByMaterial> drilled_replay;
  const bool drilled = runtime::drilledDuring(original);
  if ((options.anatomy || drilled) && !original.records.empty()) {
    if (options.anatomy) anatomy_loading = anatomy_promise.get_future();
    drilled_replay = std::async(std::launch::async, [&original, &why, &anatomy_promise, drilled] {
      return reloadScene(original, drilled, why, anatomy_promise);
    });
  }
  const Anonymized anonymized(options.anonymize, original, reference_given);
  const Recording& recording = anonymized.recording ? *anonymized.recording : original;
  const Recording* reference = anonymized.reference ? anonymized.reference.get() : reference_given;
  const std::string title = options.anonymize ? std::string(runtime::kAnonymized) : title_given;
  const std::string reference_title = options.anonymize ? std::string("reference") : reference_title_given;
  std::unique_ptr<Anatomy> anatomy;
  const SessionMetrics m = runtime::computeSessionMetrics(recording, options.metrics);
  // The reference is checked before anything is drawn: another scene is refused.
  std::unique_ptr<runtime::ReferenceComparison> comparison;
  if (reference != nullptr) {
    const SessionMetrics rm = runtime::computeSessionMetrics(*reference, options.metrics);
    comparison = std::make_unique<runtime::ReferenceComparison>(
        runtime::compareWithReference(recording, m, *reference, rm, options.dtw_samples));
  }
  std::string html = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>Session report: " +
                     escapeHtml(title) + "</title>\n" + kStyle + "</head>\n<body>\n";
  html += "<h1>Session report: " + escapeHtml(title) + "</h1>\n" + metadataLine(recording, m);
  if (!m.notices.empty()) {
    html += "<div class=\"notice\"><b>Read with notices</b>: this report shows what could be read.<ul>\n";
    for (const std::string& n : m.notices) html += "<li>" + escapeHtml(n) + "</li>\n";
    html += "</ul></div>\n";
  }
  html += summaryTable(runtime::metricValues(m));
  const std::array<MapView, 3> views = mapViews(recording);
  if (comparison) {
    if (anatomy_loading.valid()) anatomy = anatomy_loading.get();
    html += comparisonSection(*comparison, reference_title, views, options, anatomy.get());
  }
  if (!recording.records.empty()) {
    html += "<h2>Force</h2>\n" + imageTag(forceChart(recording, m, options), "force and torque over time");
    html += "<h2>Motion</h2>\n" + imageTag(speedChart(recording, m, options), "speed of the device over time");
    if (anatomy_loading.valid()) anatomy = anatomy_loading.get();
    html += "<h2>Where the tool touched</h2>\n<p class=\"small\">The proxy's position at each tick in contact, "
            "coloured by |F|, on three views in the patient's frame (letters at the sides: L/R left/right, A/P "
            "anterior/posterior, S/I superior/inferior), each seen from the side the tool was on and framed on at "
            "least " + formatNumber(kMinField_mm) + " mm around the contacts";
    if (anatomy) html += ", over the felt surface (lit from above-left of the viewer, darker when farther)";
    else if (options.anatomy)
      html += "; the scan could not be reloaded to draw it behind (" + escapeHtml(runtime::scrubText(why, anonymized.ids)) + ")";
    html += ".</p>\n" + contactMap(recording, m, options, anatomy.get());
  }
  html += "<h2>Segments</h2>\n" + segmentsTable(m);
  if (drilled_replay.valid()) html += detail::drilledByMaterialSection(drilled_replay.get(), anonymized.ids);
  html += "<h2>Proximity</h2>\n" + proximitySection(recording, m, options);
  html += "<h2>Events</h2>\n" + eventsTable(recording);
  // The jerk measures are for research (their numbers mean something only beside the same task's
  // other sessions): an appendix, with what they mean, not among the figures a teacher reads.
  std::vector<MetricValue> teaching, smoothness;
  for (const MetricValue& v : runtime::metricValues(m))
    (v.key.find("jerk") != std::string::npos ? smoothness : teaching).push_back(v);
  html += "<h2>All metrics</h2>\n<p class=\"small\">Speed is of the device (the hand), central differences "
          "over " + formatQuantity(options.metrics.derivative_step_s, "s") +
          ", placements (Touch the Surface, Home, Reset Device) left out; times are servo ticks times the servo "
          "period. Crossings into the surface are not in a recording: <code>volume-haptics run --check</code> "
          "measures them.</p>\n" +
          metricsTable(teaching);
  html += "<h2>Appendix: smoothness of the hand's motion (research measures)</h2>\n<p class=\"small\">How smooth "
          "the device's path was, as Hogan &amp; Sternad (2009) measure it: the jerk (the third derivative of the "
          "position) squared and integrated, made dimensionless by the movement's duration and peak speed. A "
          "smoother motion has a smaller dimensionless jerk and a higher log dimensionless jerk. The values "
          "depend on the task (the path's length and duration, the pauses in it), so compare them between "
          "sessions of the same task or against an expert's recording of it, not with a fixed range.</p>\n" +
          metricsTable(smoothness);
  html += "<h2>Sources</h2>\n<ul class=\"small\"><li>N. Hogan, D. Sternad, \"Sensitivity of smoothness measures "
          "to movement duration, amplitude, and arrests\", J. Motor Behavior 41(6), 2009.</li>\n<li>H. Sakoe, "
          "S. Chiba, \"Dynamic programming algorithm optimization for spoken word recognition\", IEEE Trans. "
          "ASSP 26(1), 1978.</li></ul>\n</body>\n</html>\n";
  return html;
}

void writeSessionReport(const Recording& recording, const std::string& title, const fs::path& html_path,
                        const SessionReportOptions& options, const Recording* reference,
                        const std::string& reference_title) {
  const std::string html = sessionReportHtml(recording, title, options, reference, reference_title);
  io::PrivateOutput file(html_path);  // 0600, renamed into place only when whole
  file.stream() << html;
  file.commit();
}

std::vector<std::string> writeSessionReport(const fs::path& recording_path, const fs::path& html_path,
                                            const SessionReportOptions& options, const fs::path& reference_path) {
  Recording recording = runtime::readRecording(recording_path);
  if (options.anonymize) {  // the reader's warnings name the file
    for (std::string& w : recording.warnings) w = runtime::scrubText(w, runtime::pathIdentifiers(recording_path));
  }
  std::unique_ptr<Recording> reference;
  if (!reference_path.empty()) reference = std::make_unique<Recording>(runtime::readRecording(reference_path));
  writeSessionReport(recording, recording_path.filename().string(), html_path, options, reference.get(),
                     reference_path.filename().string());
  std::vector<std::string> notices = recording.warnings;
  if (recording.records.empty()) notices.push_back("the recording holds no ticks");
  return notices;
}

}  // namespace vh::ui
