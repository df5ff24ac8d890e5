#pragma once
/// @file
/// The Replay dock's timeline widget (replay_controller.h): |F| over a recording's time, its
/// markers and the cursor, scrubbed with the mouse. GUI thread only.

#include <cstddef>
#include <vector>

#include <QRectF>
#include <QSize>
#include <QStringList>
#include <QWidget>

class QMouseEvent;
class QPaintEvent;

namespace vh::ui {

/// The replay's timeline: |F| [N] over the recording's time as a filled curve (per pixel column
/// the largest |F| of the records under it, so short peaks stay visible), markers as vertical
/// lines with their labels, and the cursor. Click or drag to scrub.
class ForceTimeline : public QWidget {
  Q_OBJECT

 public:
  explicit ForceTimeline(QWidget* parent = nullptr);
  /// One sample per record: time [s] and |F| [N] (same length; times non-decreasing).
  void setSamples(std::vector<double> time_s, std::vector<double> force_N);
  /// Markers: times [s] and labels.
  void setMarkers(std::vector<double> time_s, QStringList labels);
  void setCursor_s(double t_s);
  double cursor_s() const noexcept { return cursor_s_; }
  /// Samples held (one per record; the painting decimates to the widget's width).
  std::size_t sampleCount() const noexcept { return time_s_.size(); }
  double duration_s() const noexcept { return time_s_.empty() ? 0.0 : time_s_.back() - time_s_.front(); }
  double maxForce_N() const noexcept { return max_force_N_; }
  /// The time [s] under widget x coordinate `x` (clamped to the recording).
  double timeAtX(double x) const;
  double xAtTime(double t_s) const;
  QSize sizeHint() const override;

 signals:
  /// The user clicked or dragged to `t_s`.
  void scrubbed(double t_s);

 protected:
  void paintEvent(QPaintEvent* event) override;
  void mousePressEvent(QMouseEvent* event) override;
  void mouseMoveEvent(QMouseEvent* event) override;

 private:
  QRectF plotRect() const;
  std::vector<double> time_s_;
  std::vector<double> force_N_;
  std::vector<double> marker_s_;
  QStringList marker_labels_;
  double max_force_N_ = 0.0;
  double cursor_s_ = 0.0;
};

}  // namespace vh::ui
