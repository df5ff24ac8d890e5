#pragma once
/// @file
/// The haptics dock panel: start / stop the haptic thread, the tool (built-in and shared meshes),
/// its point-shell spacing and the resulting point count, the coupling's linear [N/m] and
/// torsional [N*m/rad] stiffness (applied live), and the device in use with its limits. The
/// panel only edits and shows values; MainWindow acts on its signals.

#include <vector>

#include <QString>
#include <QStringList>
#include <QWidget>

#include "vh/haptics/virtual_coupling.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/range_spin_box.h"
#include "vh/ui/tool_catalog.h"

class QCheckBox;
class QComboBox;
class QGroupBox;
class QHBoxLayout;
class QLabel;
class QPushButton;
class QTimer;

namespace vh::ui {

class HapticsPanel : public QWidget {
  Q_OBJECT

 public:
  explicit HapticsPanel(QWidget* parent = nullptr);

  /// The tool list and the entry in use.
  /// Shows `session`: running / available (not while `replaying`), gains, the tool `tool_index`
  /// of `tools` and its point shell, the device's name and limits (`hardware_limits` when the
  /// device picker opened it, else what the device reports).
  void showSession(const runtime::Session& session, const std::vector<ToolChoice>& tools, int tool_index,
                   const QString& hardware_limits, bool replaying);
  void setTools(const std::vector<ToolChoice>& tools, int current);
  int currentTool() const;
  /// The spacing in use [m] and the point count it gave.
  void setPointShell(double spacing_m, std::size_t point_count);
  /// Spacing the spin box shows [m].
  double pointSpacing_m() const;
  /// While a tool is being rebuilt: the point count reads "building..." and tool edits wait.
  void setBuilding(bool building);
  void setGains(const haptics::CouplingGains& gains);
  haptics::CouplingGains gains() const;
  /// Whether the haptic thread runs (button text), and whether there is one at all.
  void setRunning(bool running, bool available);
  /// The device's name and a line (or lines) of its limits.
  void setDevice(const QString& name, const QString& limits);
  /// The device picker's entries (entry 0: the simulated device), the one in use (-1: none of
  /// them, e.g. a device named by the scene file) and the catalog's problems (tooltip; empty:
  /// none). Emits nothing.
  void setDeviceChoices(const QStringList& labels, int current, const QString& problems);
  /// Selects entry `index` of the picker (-1: none). Emits nothing.
  void setDeviceChoice(int index);

  QPushButton* startStopButton() const noexcept { return start_stop_; }
  QComboBox* toolBox() const noexcept { return tool_; }
  /// The numeric fields: a number typed outside a box's range is not taken; the box says the
  /// range (RangeSpinBox) and message() repeats it for the status bar.
  RangeSpinBox* spacingBox() const noexcept { return spacing_mm_; }
  RangeSpinBox* linearStiffnessBox() const noexcept { return linear_; }
  RangeSpinBox* torsionalStiffnessBox() const noexcept { return torsional_; }
  /// CouplingGains::passivity_control.
  QCheckBox* passivityControlBox() const noexcept { return passivity_; }
  QLabel* pointCountLabel() const noexcept { return points_; }
  /// How closely the tool's mesh is felt (runtime::feltGap()): the largest gap between the mesh
  /// and the felt points and edges, in warning colours past haptics::kShellGapWarning_m.
  QLabel* feltGapLabel() const noexcept { return felt_gap_; }
  /// ToolSpec::edge_test: the tool's surface between its points kept outside too.
  QCheckBox* edgeTestBox() const noexcept { return edge_test_; }
  /// The fit check's verdict on this computer (runtime/tool_fit.h), in warning colours when
  /// `late`; with a suggested spacing [m] > 0, a button that rebuilds the tool at it
  /// (toolRequested()).
  void showToolFit(const QString& text, bool late, double suggested_spacing_m = 0.0, std::size_t suggested_points = 0);
  QLabel* toolFitLabel() const noexcept { return fit_; }
  /// "Use 1.77 mm (1,997 points)": shown when the fit check suggests a spacing.
  QPushButton* useFittingSpacingButton() const noexcept { return use_fit_; }
  QComboBox* deviceBox() const noexcept { return device_choice_; }
  QPushButton* rescanButton() const noexcept { return rescan_; }

 signals:
  void startStopRequested(bool run);
  /// The user picked a tool or a spacing (debounced 400 ms for the spin box): rebuild.
  void toolRequested(int choice_index, double point_spacing_m);
  void gainsChanged(const haptics::CouplingGains& gains);
  /// The user switched the edge test between shell points (ToolSpec::edge_test).
  void edgeTestRequested(bool on);
  void resetDeviceRequested();
  /// The user picked entry `index` of the device picker.
  void deviceChoiceRequested(int index);
  /// The user asked for the devices to be listed again.
  void rescanRequested();
  /// A line for the status bar (a number typed out of a box's range was not taken).
  void message(const QString& text, int timeout_ms);

 private:
  QPushButton* start_stop_;
  QPushButton* reset_device_;
  QComboBox* tool_;
  RangeSpinBox* spacing_mm_;
  QLabel* points_;
  QLabel* felt_gap_;
  QCheckBox* edge_test_;
  QLabel* fit_;
  QPushButton* use_fit_;
  double fit_spacing_m_ = 0.0;  ///< The spacing use_fit_ asks for [m]; 0: none.
  RangeSpinBox* linear_;
  RangeSpinBox* torsional_;
  QCheckBox* passivity_;
  QComboBox* device_choice_;
  QPushButton* rescan_;
  QLabel* device_name_;
  QLabel* device_limits_;
  QTimer* spacing_timer_;
  bool running_ = false;
  bool updating_ = false;  // programmatic changes emit nothing
  // The felt gap of the tool last shown (measured once per tool and edge setting).
  const void* gap_tool_ = nullptr;
  bool gap_edges_ = false;
  void showFeltGap(const runtime::Session& session);
  // The constructor's groups, top to bottom, then the controls' signals.
  QHBoxLayout* buildButtons();  ///< Start / stop and reset device.
  QGroupBox* buildToolBox();    ///< The tool's mesh, point spacing, points, felt gap and edge test.
  QGroupBox* buildCouplingBox();  ///< The virtual coupling's stiffnesses and passivity control.
  QGroupBox* buildDeviceBox();    ///< The device choice, rescan, name and limits.
  void connectControls();
};

}  // namespace vh::ui
