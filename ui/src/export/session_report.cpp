#include "vh/ui/export/session_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <future>
#include <memory>
#include <stdexcept>

#include <QBuffer>
#include <QByteArray>
#include <QGraphicsScene>
#include <QGraphicsLayout>
#include <QImage>
#include <QPainter>
#include <QPen>
#include <QtCharts/QChart>
#include <QtCharts/QLegendMarker>
#include <QtCharts/QLineSeries>
#include <QtCharts/QScatterSeries>
#include <QtCharts/QValueAxis>

#include <nlohmann/json.hpp>

#include "vh/haptics/scalar_volume.h"
#include "vh/io/private_files.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metadata.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using runtime::MetricValue;
using runtime::Recording;
using runtime::SessionMetrics;
using runtime::TickRecord;

double norm3(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

std::string escapeHtml(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

/// A number for people: 4 significant digits, integers as such.
std::string number(double v) {
  char buf[64];
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 1e15) std::snprintf(buf, sizeof buf, "%.0f", v);
  else std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

/// Renders `chart` (owned here) off screen and returns it as a data: URI of a PNG. A non-null
/// `plot_background` is drawn stretched over the plot area, under the series and grid.
std::string chartImage(QChart* chart, int width, int height, const QImage& plot_background = QImage()) {
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
    if (!plot_background.isNull()) {
      chart->setBackgroundVisible(false);
      chart->setPlotAreaBackgroundVisible(false);
      painter.setRenderHint(QPainter::SmoothPixmapTransform);
      painter.drawImage(chart->plotArea(), plot_background);
    }
    scene.render(&painter, QRectF(0, 0, width, height), QRectF(0, 0, width, height));
  }
  QByteArray png;
  QBuffer buffer(&png);
  buffer.open(QIODevice::WriteOnly);
  if (!image.save(&buffer, "PNG")) throw std::runtime_error("a chart could not be encoded as PNG");
  return "data:image/png;base64," + png.toBase64().toStdString();
}

std::string imageTag(const std::string& uri, const std::string& alt, const char* cls = "chart") {
  return "<img class=\"" + std::string(cls) + "\" alt=\"" + escapeHtml(alt) + "\" src=\"" + uri + "\">\n";
}

QValueAxis* addAxis(QChart* chart, Qt::Alignment where, const QString& title, double lo, double hi) {
  auto* axis = new QValueAxis;
  axis->setTitleText(title);
  if (!(hi > lo)) hi = lo + 1.0;
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
    std::size_t best = b;
    double best_v = value(records[b]);
    for (std::size_t i = b + 1; i < std::min(n, b + per); ++i) {
      const double v = value(records[i]);
      if (v > best_v) best_v = v, best = i;
    }
    out.append(QPointF(records[best].time_s, best_v));
  }
  return out;
}

/// The events worth a mark on the time charts: markers and critical contacts / removals.
bool markedEvent(const runtime::RecordingEvent& e) {
  return e.type == "marker" || e.type == "critical_removed" || e.type == "critical_contact";
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
  const double fmax = std::max(m.max_force_N, m.force_threshold_N) * 1.1;
  QValueAxis* yf = addAxis(chart, Qt::AlignLeft, "|F| [N]", 0.0, fmax > 0 ? fmax : 1.0);
  QValueAxis* yt = addAxis(chart, Qt::AlignRight, "|torque| [N*m]", 0.0, m.max_torque_Nm > 0 ? m.max_torque_Nm * 1.1 : 1.0);
  yf->applyNiceNumbers();
  yt->applyNiceNumbers();
  QLineSeries* f = lineSeries("|F| [N]", QColor(0x1f, 0x77, 0xb4));
  f->replace(force);
  QLineSeries* t = lineSeries("|torque| [N*m]", QColor(0xff, 0x7f, 0x0e), 1.0);
  t->replace(torque);
  QLineSeries* thr = lineSeries(QString("threshold %1 N").arg(m.force_threshold_N), QColor(0xd6, 0x27, 0x28), 1.0,
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
    if (markedEvent(e)) marks->append(e.time_s, fmax * 0.97);
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
  const double dt = 1.0 / m.servo_rate_Hz;
  const std::size_t k = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(o.metrics.derivative_step_s / dt)));
  QList<QPointF> points;
  const std::size_t stride = std::max<std::size_t>(1, r.size() / 2000);
  double vmax = 0.0;
  for (std::size_t i = k; i + k < r.size(); i += stride) {
    double d2 = 0.0;
    for (int c = 0; c < 3; ++c) d2 += std::pow(r[i + k].p_WD_m[c] - r[i - k].p_WD_m[c], 2);
    const double v = std::sqrt(d2) / (r[i + k].time_s - r[i - k].time_s);
    if (!std::isfinite(v)) continue;
    vmax = std::max(vmax, v);
    points.append(QPointF(r[i].time_s, v));
  }
  QValueAxis* x = addAxis(chart, Qt::AlignBottom, "time [s]", r.front().time_s, r.back().time_s);
  x->applyNiceNumbers();
  QValueAxis* y = addAxis(chart, Qt::AlignLeft, "speed [m/s]", 0.0, vmax > 0 ? vmax * 1.1 : 1.0);
  y->applyNiceNumbers();
  QLineSeries* s = lineSeries("speed", QColor(0x94, 0x67, 0xbd));
  s->replace(points);
  chart->addSeries(s);
  s->attachAxis(x);
  s->attachAxis(y);
  return chartImage(chart, o.chart_width, o.chart_height * 3 / 4);
}

/// Axis ranges of equal span around the points' centre (both axes of a projection to scale).
void equalRanges(const QList<QPointF>& pts, double& x0, double& x1, double& y0, double& y1) {
  double ax = 1e300, bx = -1e300, ay = 1e300, by = -1e300;
  for (const QPointF& p : pts) {
    ax = std::min(ax, p.x()), bx = std::max(bx, p.x()), ay = std::min(ay, p.y()), by = std::max(by, p.y());
  }
  if (pts.isEmpty()) ax = ay = -0.01, bx = by = 0.01;
  const double half = std::max({(bx - ax) / 2, (by - ay) / 2, 1.0}) * 1.1;  // mm
  const double cx = (ax + bx) / 2, cy = (ay + by) / 2;
  x0 = cx - half, x1 = cx + half, y0 = cy - half, y1 = cy + half;
}

/// The felt surface of the recorded scene, for the contact map's background.
struct Anatomy {
  std::shared_ptr<const haptics::ScalarVolume> field;  ///< The felt field, in W [m].
  double isovalue = 0.0;                               ///< Its surface's level.
};

/// The felt surface seen from +c, the axis normal to the plane (a, b) of W, over [x0, x1] x
/// [y0, y1] [mm]: each pixel's ray is marched down c (steps of a voxel, at most 160 per ray) to
/// its first point inside the surface, shaded by that point's height (nearer the viewer:
/// lighter), transparent where the ray meets nothing. Row 0 is the top (largest b).
QImage anatomyProjection(const Anatomy& anatomy, int a, int b, double x0, double x1, double y0, double y1) {
  constexpr int kPixels = 110;
  const int c = 3 - a - b;
  const haptics::ScalarVolume& f = *anatomy.field;
  const Eigen::Vector3d lo = f.boundsMin_W_m(), hi = f.boundsMax_W_m();
  const double step = std::max(f.geometry().minSpacing(), (hi[c] - lo[c]) / 160.0);
  QImage image(kPixels, kPixels, QImage::Format_ARGB32);
  image.fill(Qt::transparent);
  for (int row = 0; row < kPixels; ++row) {
    for (int col = 0; col < kPixels; ++col) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      p[a] = (x0 + (x1 - x0) * (col + 0.5) / kPixels) * 1e-3;
      p[b] = (y1 - (y1 - y0) * (row + 0.5) / kPixels) * 1e-3;
      if (p[a] < lo[a] || p[a] > hi[a] || p[b] < lo[b] || p[b] > hi[b]) continue;
      for (double z = hi[c]; z >= lo[c]; z -= step) {
        p[c] = z;
        if (!f.isInside(p, anatomy.isovalue)) continue;
        const double height = (z - lo[c]) / std::max(hi[c] - lo[c], 1e-9);
        const int grey = static_cast<int>(130 + 100 * height);
        image.setPixelColor(col, row, QColor(grey, grey - 4, grey - 12));
        break;
      }
    }
  }
  return image;
}

/// One projection chart (plane axes a, b of W) of the given series, equal scales, over the
/// anatomy's projection when given.
std::string projectionChart(const QString& title, int a, int b, std::vector<QXYSeries*> series,
                            const std::vector<QList<QPointF>>& data, bool legend, int size,
                            const Anatomy* anatomy = nullptr) {
  auto* chart = new QChart;
  chart->setTitle(title);
  if (!legend) chart->legend()->hide();
  QList<QPointF> all;
  for (const auto& d : data) all += d;
  double x0, x1, y0, y1;
  equalRanges(all, x0, x1, y0, y1);
  static const char* kAxis[] = {"x", "y", "z"};
  QValueAxis* ax = addAxis(chart, Qt::AlignBottom, QString("%1 [mm]").arg(kAxis[a]), x0, x1);
  QValueAxis* ay = addAxis(chart, Qt::AlignLeft, QString("%1 [mm]").arg(kAxis[b]), y0, y1);
  ax->applyNiceNumbers();
  ay->applyNiceNumbers();
  for (std::size_t i = 0; i < series.size(); ++i) {
    series[i]->replace(data[i]);
    chart->addSeries(series[i]);
    series[i]->attachAxis(ax);
    series[i]->attachAxis(ay);
  }
  QImage background;
  if (anatomy != nullptr)
    background = anatomyProjection(*anatomy, a, b, ax->min(), ax->max(), ay->min(), ay->max());
  return chartImage(chart, size, size + (legend ? 40 : 0), background);
}

QPointF project(const double p[3], int a, int b) { return QPointF(p[a] * 1e3, p[b] * 1e3); }

/// The contact map: proxy positions in contact on the three planes, in four force bands.
std::string contactMap(const Recording& rec, const SessionMetrics& m, const SessionReportOptions& o,
                       const Anatomy* anatomy) {
  std::vector<const TickRecord*> contacts;
  for (const TickRecord& r : rec.records)
    if (r.contacts > 0) contacts.push_back(&r);
  if (contacts.empty()) return "<p>The tool touched nothing: no contact map.</p>\n";
  const std::size_t stride = std::max<std::size_t>(1, contacts.size() / 3000);
  const double fmax = std::max(m.max_force_N, 1e-9);
  static const QColor kBand[] = {QColor(0x31, 0x82, 0xbd), QColor(0x31, 0xa3, 0x54), QColor(0xfd, 0x8d, 0x3c),
                                 QColor(0xde, 0x2d, 0x26)};
  std::string html = "<div class=\"maps\">\n";
  const int planes[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (const auto& plane : planes) {
    std::vector<QXYSeries*> series;
    std::vector<QList<QPointF>> data(4);
    for (int band = 0; band < 4; ++band) {
      auto* s = new QScatterSeries;
      s->setName(QString("%1-%2").arg(fmax * band / 4, 0, 'g', 2).arg(fmax * (band + 1) / 4, 0, 'g', 2));
      s->setMarkerSize(5);
      s->setColor(kBand[band]);
      s->setBorderColor(kBand[band]);
      series.push_back(s);
    }
    for (std::size_t i = 0; i < contacts.size(); i += stride) {
      const double f = norm3(contacts[i]->force_W_N);
      const int band = std::min(3, static_cast<int>(f / fmax * 4.0));
      data[static_cast<std::size_t>(band)].append(project(contacts[i]->p_WP_m, plane[0], plane[1]));
    }
    static const char* kAxis[] = {"x", "y", "z"};
    const QString title = QString("Contacts, %1-%2 plane, |F| [N]").arg(kAxis[plane[0]]).arg(kAxis[plane[1]]);
    html += imageTag(projectionChart(title, plane[0], plane[1], series, data, true, o.map_size, anatomy),
                     title.toStdString(), "map");
  }
  return html + "</div>\n";
}

std::string pathsChart(const runtime::ReferenceComparison& c, int a, int b, int size, const Anatomy* anatomy) {
  std::vector<QList<QPointF>> data(2);
  for (const auto& p : c.session_path) data[0].append(QPointF(p[a] * 1e3, p[b] * 1e3));
  for (const auto& p : c.reference_path) data[1].append(QPointF(p[a] * 1e3, p[b] * 1e3));
  static const char* kAxis[] = {"x", "y", "z"};
  const QString title = QString("Device paths, %1-%2 plane").arg(kAxis[a]).arg(kAxis[b]);
  return imageTag(projectionChart(title, a, b,
                                  {lineSeries("this session", QColor(0x1f, 0x77, 0xb4)),
                                   lineSeries("reference", QColor(0x7f, 0x7f, 0x7f), 1.5, Qt::DashLine)},
                                  data, true, size, anatomy),
                  title.toStdString(), "map");
}

std::string metricsTable(const std::vector<MetricValue>& values) {
  std::string html = "<table>\n<tr><th>metric</th><th>value</th><th>unit</th><th>column</th></tr>\n";
  for (const MetricValue& v : values)
    html += "<tr><td>" + escapeHtml(v.label) + "</td><td class=\"n\">" + number(v.value) + "</td><td>" +
            escapeHtml(v.unit) + "</td><td><code>" + v.key + "</code></td></tr>\n";
  return html + "</table>\n";
}

std::string segmentsTable(const SessionMetrics& m) {
  if (m.segments.empty())
    return "<p>The recording names no segments (no segmentation was open), so no time per segment.</p>\n";
  std::string html =
      "<table>\n<tr><th>segment</th><th>critical</th><th>time in contact [s]</th><th>touches</th>"
      "<th>peak |F| [N]</th><th>drilled away (critical) [voxels]</th><th>[mm^3]</th></tr>\n";
  for (const auto& s : m.segments)
    html += "<tr" + std::string(s.critical ? " class=\"critical\"" : "") + "><td>" + escapeHtml(s.name) + "</td><td>" +
            (s.critical ? "yes" : "no") + "</td><td class=\"n\">" + number(s.time_in_contact_s) +
            "</td><td class=\"n\">" + number(static_cast<double>(s.touches)) + "</td><td class=\"n\">" +
            number(s.peak_force_N) + "</td><td class=\"n\">" + number(static_cast<double>(s.removed_voxels)) +
            "</td><td class=\"n\">" + number(s.removed_mm3) + "</td></tr>\n";
  return html + "</table>\n";
}

std::string eventsTable(const Recording& rec) {
  if (rec.events.empty()) return "<p>No events were recorded.</p>\n";
  constexpr std::size_t kMaxRows = 300;
  std::string html = "<table>\n<tr><th>t [s]</th><th>event</th><th>detail</th></tr>\n";
  std::size_t rows = 0;
  for (const auto& e : rec.events) {
    if (rows++ == kMaxRows) break;
    html += "<tr" + std::string(markedEvent(e) ? " class=\"critical\"" : "") + "><td class=\"n\">" + number(e.time_s) +
            "</td><td>" + escapeHtml(e.type) + "</td><td><code>" + escapeHtml(e.detail_json) + "</code></td></tr>\n";
  }
  html += "</table>\n";
  if (rec.events.size() > kMaxRows)
    html += "<p>" + std::to_string(rec.events.size() - kMaxRows) + " more events: `volume-haptics export --events-csv` lists them all.</p>\n";
  return html;
}

std::string comparisonSection(const runtime::ReferenceComparison& c, const std::string& reference_title,
                              const SessionReportOptions& o, const Anatomy* anatomy) {
  std::string html = "<h2>Against the reference " + escapeHtml(reference_title) + "</h2>\n";
  html += "<p>Mean distance between the two device paths after aligning them in time by dynamic time "
          "warping (Sakoe &amp; Chiba 1978), each thinned to " +
          std::to_string(c.path_samples) + " points: <b>" + number(c.alignment.mean_distance_m * 1e3) +
          " mm</b> (" + std::to_string(c.alignment.path.size()) +
          " aligned pairs). Both recordings are in the same scene frame, so the paths are compared "
          "without moving either.</p>\n";
  html += "<div class=\"maps\">\n" + pathsChart(c, 0, 1, o.map_size + 80, anatomy) + pathsChart(c, 0, 2, o.map_size + 80, anatomy) +
          "</div>\n";
  html += "<table>\n<tr><th>metric</th><th>this session</th><th>reference</th><th>difference</th><th>unit</th></tr>\n";
  for (std::size_t i = 0; i < c.session.size() && i < c.reference.size(); ++i)
    html += "<tr><td>" + escapeHtml(c.session[i].label) + "</td><td class=\"n\">" + number(c.session[i].value) +
            "</td><td class=\"n\">" + number(c.reference[i].value) + "</td><td class=\"n\">" +
            number(c.session[i].value - c.reference[i].value) + "</td><td>" + escapeHtml(c.session[i].unit) +
            "</td></tr>\n";
  return html + "</table>\n";
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
  row("servo rate", number(m.servo_rate_Hz) + " Hz");
  return html + "</table>\n";
}

/// The recorded scene's felt surface (its scan, or its felt segments), reloaded from the
/// metadata; null with `why` set when it cannot be (a missing or changed dataset).
std::unique_ptr<Anatomy> loadAnatomy(const Recording& rec, std::string& why) {
  try {
    runtime::SceneSpec spec = runtime::sceneFromSessionMetadata(rec.metadata_json);
    spec.device.reset();
    spec.openigtlink.reset();
    const runtime::LoadedScene scene = runtime::loadScene(spec);
    auto anatomy = std::make_unique<Anatomy>();
    anatomy->field = scene.hapticField();
    anatomy->isovalue = scene.hapticIsovalue();
    if (anatomy->field == nullptr || anatomy->field->empty()) throw std::runtime_error("the scene has no volume");
    return anatomy;
  } catch (const std::exception& e) {
    why = e.what();
    return nullptr;
  }
}

constexpr const char* kStyle = R"(<style>
body { font-family: sans-serif; margin: 2em; color: #222; max-width: 1100px; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid #ddd; padding: 2px 8px; text-align: left; }
td.n { text-align: right; font-variant-numeric: tabular-nums; } tr.critical td { background: #fde0dc; }
table.meta th { background: #f4f4f4; } .notice { background: #fff3cd; border: 1px solid #e0b000; padding: 0.6em 1em; }
img.chart { display: block; max-width: 100%; } .maps { display: flex; flex-wrap: wrap; gap: 8px; }
.small { color: #666; font-size: 0.9em; }
</style>
)";

}  // namespace

std::string sessionReportHtml(const Recording& recording, const std::string& title,
                              const SessionReportOptions& options, const Recording* reference,
                              const std::string& reference_title) {
  if (options.chart_width < 64 || options.chart_height < 64 || options.map_size < 64)
    throw std::invalid_argument("report charts must be at least 64 pixels wide and high");
  // The scan is reloaded on a second thread while the metrics and the time charts are drawn.
  std::string why;
  std::future<std::unique_ptr<Anatomy>> anatomy_loading;
  if (options.anatomy && !recording.records.empty())
    anatomy_loading = std::async(std::launch::async, [&recording, &why] { return loadAnatomy(recording, why); });
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
  if (!recording.records.empty()) {
    html += "<h2>Force</h2>\n" + imageTag(forceChart(recording, m, options), "force and torque over time");
    html += "<h2>Motion</h2>\n" + imageTag(speedChart(recording, m, options), "speed of the device over time");
    if (anatomy_loading.valid()) anatomy = anatomy_loading.get();
    html += "<h2>Where the tool touched</h2>\n<p class=\"small\">The proxy's position at each tick in "
            "contact (scene frame, mm), coloured by |F|";
    if (anatomy) html += ", over the felt surface seen from the third axis' positive side (grey: lighter is nearer)";
    else if (options.anatomy) html += "; the scan could not be reloaded to draw it behind (" + escapeHtml(why) + ")";
    html += ".</p>\n" + contactMap(recording, m, options, anatomy.get());
  }
  html += "<h2>Metrics</h2>\n<p class=\"small\">Speed and jerk are of the device (the hand), central differences "
          "over " + number(options.metrics.derivative_step_s * 1e3) +
          " ms; jerk as Hogan &amp; Sternad (2009); times are servo ticks times the servo period. Crossings "
          "into the surface are not in a recording: <code>volume-haptics run --check</code> measures them.</p>\n" +
          metricsTable(runtime::metricValues(m));
  html += "<h2>Segments</h2>\n" + segmentsTable(m);
  html += "<h2>Events</h2>\n" + eventsTable(recording);
  if (comparison) html += comparisonSection(*comparison, reference_title, options, anatomy.get());
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
  const Recording recording = runtime::readRecording(recording_path);
  std::unique_ptr<Recording> reference;
  if (!reference_path.empty()) reference = std::make_unique<Recording>(runtime::readRecording(reference_path));
  writeSessionReport(recording, recording_path.filename().string(), html_path, options, reference.get(),
                     reference_path.filename().string());
  std::vector<std::string> notices = recording.warnings;
  if (recording.records.empty()) notices.push_back("the recording holds no ticks");
  return notices;
}

}  // namespace vh::ui
