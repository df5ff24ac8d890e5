#pragma once
/// @file
/// The Segments dock's panel: the segments of a 3D Slicer segmentation or label map
/// with their colours, and for each whether it is felt (the hand feels its smoothed surface
/// instead of the scan's isosurface), shown (a coloured surface beside the ray-cast scan) and
/// critical (touching it is an alert and an event in the recording); the felt surface's
/// smoothing; whether the shown segments are drawn through the scan (in front of its surface,
/// which hides a segment inside the body); the segment touched now. It edits and shows; the main window acts on its signals
/// (runtime::Session::setSegments()). GUI thread only.
#include <array>
#include <map>
#include <string>
#include <vector>

#include <QMetaType>
#include <QWidget>

#include "vh/runtime/critical_proximity.h"

#include "vh/runtime/segments.h"
#include "vh/ui/panels/range_spin_box.h"

class QCheckBox;
class QLabel;
class QPushButton;
class QTableWidget;
class QTableWidgetItem;

namespace vh::ui {

/// The choices the panel shows: indices into the segmentation's segments.
struct SegmentChoices {
  std::vector<int> felt, shown, critical;
  double smoothing_voxels = 1.0;
  /// Warning and alarm distances per segment (one per row; used for the critical ones) [m].
  std::vector<runtime::ProximityThresholds> thresholds;
  bool operator==(const SegmentChoices&) const = default;
};

class SegmentsPanel : public QWidget {
  Q_OBJECT

 public:
  /// Table columns.
  enum Column { kName = 0, kFelt = 1, kShown = 2, kCritical = 3, kHardness = 4, kWarn = 5, kAlarm = 6 };

  explicit SegmentsPanel(QWidget* parent = nullptr);

  /// Shows `set`'s segments and choices (null: none, with a hint how to open some). No signal.
  void showSegments(const runtime::SegmentSet* set);
  /// Shows each segment's drilling hardness [J/mm^3] (by name or ID; a segment not in the map
  /// shows an empty cell: the default from its HU). No signal.
  void showHardness(const std::map<std::string, double>& hardness_J_per_mm3);
  /// Marks the row of the touched segment (-1: none) and says so under the table.
  void setTouched(int segment);
  /// Shows segment `segment`'s swatch in `rgb` (0..1): the colour the view draws it in when that
  /// is not its file's. No signal.
  void setDisplayColour(int segment, const std::array<double, 3>& rgb);
  /// The choices as the check boxes say now.
  SegmentChoices choices() const;
  /// Sound on touching a critical segment (the window beeps).
  bool alertSound() const;
  /// Ticks "Show segments through the scan" as `on` says (the preference shown). No signal.
  void setThroughScan(bool on);
  /// The two sound boxes as remembered (no signal).
  void setSounds(bool burr, bool alert);
  bool throughScan() const;
  /// The drilling burr's sound (ui/sound_output.h) on.
  bool burrSound() const;

  QTableWidget* table() const noexcept { return table_; }
  QPushButton* openButton() const noexcept { return open_; }
  /// The felt surface's smoothing [voxels]; a number typed out of its range is not taken.
  RangeSpinBox* smoothingBox() const noexcept { return smoothing_; }
  QCheckBox* throughScanBox() const noexcept { return through_scan_; }

 signals:
  /// A check box or the smoothing changed.
  void choicesChanged(const vh::ui::SegmentChoices& choices);
  /// "Open Segmentation..." was pressed.
  void openRequested();
  /// A hardness cell was edited to a number > 0 [J/mm^3] (anything else is refused and reverted).
  void hardnessChanged(int segment, double J_per_mm3);
  /// A segment's name was double-clicked: frame it in the view ("go to segment").
  void goToSegmentRequested(int segment);
  /// "Show segments through the scan" was ticked (true) or cleared by the user.
  void throughScanToggled(bool on);
  /// "Burr sound" was switched.
  void burrSoundToggled(bool on);
  /// "Alert sounds (critical segment near or touched, technique)" was switched.
  void alertSoundToggled(bool on);

 private:
  QLabel* source_ = nullptr;
  QTableWidget* table_ = nullptr;
  RangeSpinBox* smoothing_ = nullptr;
  QCheckBox* through_scan_ = nullptr;
  QCheckBox* sound_ = nullptr;
  QCheckBox* burr_sound_ = nullptr;
  QLabel* touched_ = nullptr;
  QPushButton* open_ = nullptr;
  std::vector<QString> names_;
  std::vector<QString> ids_;
  std::vector<bool> critical_;
  int touched_segment_ = -1;
  bool filling_ = false;

  void buildTable();
  /// A warning or alarm cell was edited: taken when 0 < alarm <= warn <= 20 mm, else put back.
  /// @return whether it was taken.
  bool takeThreshold(QTableWidgetItem* item);
};

}  // namespace vh::ui

Q_DECLARE_METATYPE(vh::ui::SegmentChoices)
