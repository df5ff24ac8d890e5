#include "vh/ui/panels/haptics_panel.h"
#include "vh/ui/devices/device_picker.h"
#include "vh/runtime/tool_fidelity.h"

#include <cmath>

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QSignalBlocker>
#include <QTimer>
#include <QVBoxLayout>

namespace vh::ui {

HapticsPanel::HapticsPanel(QWidget* parent) : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(6, 6, 6, 6);
  layout->addLayout(buildButtons());
  layout->addWidget(buildToolBox());
  layout->addWidget(buildCouplingBox());
  layout->addWidget(buildDeviceBox());
  layout->addStretch(1);

  spacing_timer_ = new QTimer(this);
  spacing_timer_->setSingleShot(true);
  spacing_timer_->setInterval(400);
  connectControls();
  setRunning(false, false);
}

QHBoxLayout* HapticsPanel::buildButtons() {
  auto* buttons = new QHBoxLayout();
  start_stop_ = new QPushButton("Start haptics", this);
  start_stop_->setObjectName("startStopHaptics");
  start_stop_->setToolTip("Start or stop the 1 kHz haptic thread (stopping ramps the force to zero)");
  reset_device_ = new QPushButton("Reset device", this);
  reset_device_->setToolTip("Move the simulated device back to the tool's starting pose");
  buttons->addWidget(start_stop_);
  buttons->addWidget(reset_device_);
  return buttons;
}

QGroupBox* HapticsPanel::buildToolBox() {
  auto* tool_box = new QGroupBox("Tool", this);
  auto* tool_form = new QFormLayout(tool_box);
  tool_ = new QComboBox(tool_box);
  tool_->setObjectName("toolChoice");
  tool_->setSizeAdjustPolicy(QComboBox::AdjustToMinimumContentsLengthWithIcon);
  tool_->setMinimumContentsLength(18);
  spacing_mm_ = new RangeSpinBox("the point spacing", tool_box);
  spacing_mm_->setObjectName("pointSpacing");
  spacing_mm_->setDecimals(2);
  spacing_mm_->setRange(0.1, 20.0);
  spacing_mm_->setSingleStep(0.1);
  spacing_mm_->setSuffix(" mm");
  spacing_mm_->setKeyboardTracking(false);
  spacing_mm_->setToolTip("Distance between neighbouring points of the tool's point shell");
  points_ = new QLabel("-", tool_box);
  points_->setObjectName("pointCount");
  tool_form->addRow("Mesh", tool_);
  tool_form->addRow("Point spacing", spacing_mm_);
  tool_form->addRow("Points", points_);
  felt_gap_ = new QLabel("-", tool_box);
  felt_gap_->setObjectName("feltGap");
  felt_gap_->setWordWrap(true);
  felt_gap_->setToolTip(
      "The largest distance between the tool's mesh and what is felt of it (its points, and with Surface "
      "between points the edges between them): a surface can come this far inside the tool before it is felt");
  tool_form->addRow("Felt within", felt_gap_);
  edge_test_ = new QCheckBox("Surface between points", tool_box);
  edge_test_->setObjectName("edgeTest");
  edge_test_->setToolTip(
      "Keep the tool's surface between its points outside the surface felt, not only the points: bone "
      "thinner than the point spacing cannot slip between them. On by default; off gives the paper's "
      "points-only proxy, for comparison with the published method (about half the solver's time)");
  tool_form->addRow(edge_test_);
  fit_ = new QLabel("-", tool_box);
  fit_->setObjectName("toolFit");
  fit_->setWordWrap(true);
  fit_->setToolTip(
      "The fit check: a warm-up of this tool on this scene (pressed, slid and twisted on the surface) says whether "
      "this computer renders it on time: its worst ticks cut by the solver's deadline at most 0.1 % of the time and "
      "the proxy at most 0.5 mm behind. When not, the finest coarser spacing that fits is offered");
  use_fit_ = new QPushButton(tool_box);
  use_fit_->setObjectName("useFittingSpacing");
  use_fit_->setVisible(false);
  use_fit_->setToolTip("Rebuild the tool at the finest point spacing this computer renders on time");
  tool_form->addRow("This computer", fit_);
  tool_form->addRow(use_fit_);
  connect(use_fit_, &QPushButton::clicked, this, [this] {
    if (fit_spacing_m_ > 0.0) emit toolRequested(currentTool(), fit_spacing_m_);
  });
  return tool_box;
}

void HapticsPanel::showToolFit(const QString& text, bool late, double suggested_spacing_m, std::size_t suggested_points) {
  fit_->setText(text);
  fit_->setStyleSheet(late ? "color: #b35900; font-weight: bold;" : "");
  fit_spacing_m_ = suggested_spacing_m;
  use_fit_->setVisible(suggested_spacing_m > 0.0);
  if (suggested_spacing_m > 0.0)
    use_fit_->setText(QString("Use %1 mm (%2 points)").arg(suggested_spacing_m * 1e3, 0, 'f', 2).arg(suggested_points));
}

QGroupBox* HapticsPanel::buildCouplingBox() {
  auto* coupling = new QGroupBox("Virtual coupling", this);
  auto* coupling_form = new QFormLayout(coupling);
  linear_ = new RangeSpinBox("the linear stiffness", coupling);
  linear_->setObjectName("linearStiffness");
  linear_->setRange(0.0, 100000.0);  // past a device's rating only with passivity control (clampGains)
  linear_->setDecimals(0);
  linear_->setSingleStep(100.0);
  linear_->setSuffix(" N/m");
  linear_->setKeyboardTracking(false);
  linear_->setToolTip("Linear stiffness k_lin of the spring between device and proxy (paper eq. 5)");
  torsional_ = new RangeSpinBox("the torsional stiffness", coupling);
  torsional_->setObjectName("torsionalStiffness");
  torsional_->setRange(0.0, 50.0);
  torsional_->setDecimals(3);
  torsional_->setSingleStep(0.1);
  torsional_->setSuffix(QString::fromUtf8(" N\u00b7m/rad"));
  torsional_->setKeyboardTracking(false);
  torsional_->setToolTip("Torsional stiffness k_ang of the coupling (paper eq. 5)");
  coupling_form->addRow("Linear", linear_);
  passivity_ = new QCheckBox("Passivity control", coupling);
  passivity_->setObjectName("passivityControl");
  passivity_->setToolTip(
      "Time-domain passivity controller (Hannaford and Ryu 2002): removes energy the sampled, delayed "
      "coupling would create, so stiffer contact stays stable; slightly softer feel on release. Off by default.");
  coupling_form->addRow("Torsional", torsional_);
  coupling_form->addRow(passivity_);
  return coupling;
}

QGroupBox* HapticsPanel::buildDeviceBox() {
  auto* device = new QGroupBox("Device", this);
  auto* device_layout = new QVBoxLayout(device);
  auto* device_row = new QHBoxLayout();
  device_choice_ = new QComboBox(device);
  device_choice_->setObjectName("deviceChoice");
  device_choice_->setSizeAdjustPolicy(QComboBox::AdjustToMinimumContentsLengthWithIcon);
  device_choice_->setMinimumContentsLength(18);
  device_choice_->setPlaceholderText("Device named by the scene");
  device_choice_->setToolTip("The device that drives the tool: the simulated one or a connected haptic device");
  rescan_ = new QPushButton("Rescan", device);
  rescan_->setObjectName("rescanDevices");
  rescan_->setToolTip("List the connected devices again");
  device_row->addWidget(device_choice_, 1);
  device_row->addWidget(rescan_);
  device_layout->addLayout(device_row);
  device_name_ = new QLabel("-", device);
  device_name_->setObjectName("deviceName");
  device_name_->setWordWrap(true);
  device_limits_ = new QLabel("", device);
  device_limits_->setObjectName("deviceLimits");
  device_limits_->setWordWrap(true);
  device_limits_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  device_layout->addWidget(device_name_);
  device_layout->addWidget(device_limits_);
  return device;
}

void HapticsPanel::connectControls() {
  connect(start_stop_, &QPushButton::clicked, this, [this] { emit startStopRequested(!running_); });
  connect(reset_device_, &QPushButton::clicked, this, &HapticsPanel::resetDeviceRequested);
  connect(rescan_, &QPushButton::clicked, this, &HapticsPanel::rescanRequested);
  connect(device_choice_, &QComboBox::activated, this, &HapticsPanel::deviceChoiceRequested);
  connect(tool_, &QComboBox::currentIndexChanged, this, [this](int index) {
    if (!updating_ && index >= 0) emit toolRequested(index, pointSpacing_m());
  });
  connect(spacing_mm_, &QDoubleSpinBox::valueChanged, this, [this] {
    if (!updating_) spacing_timer_->start();
  });
  connect(spacing_timer_, &QTimer::timeout, this, [this] { emit toolRequested(currentTool(), pointSpacing_m()); });
  auto gains_edited = [this] {
    if (!updating_) emit gainsChanged(gains());
  };
  connect(linear_, &QDoubleSpinBox::valueChanged, this, gains_edited);
  connect(torsional_, &QDoubleSpinBox::valueChanged, this, gains_edited);
  connect(passivity_, &QCheckBox::toggled, this, gains_edited);
  for (RangeSpinBox* box : {spacing_mm_, linear_, torsional_})
    connect(box, &RangeSpinBox::outOfRange, this, [this](const QString& text) { emit message(text, 8000); });
  connect(edge_test_, &QCheckBox::toggled, this, [this](bool on) {
    if (!updating_) emit edgeTestRequested(on);
  });
}

void HapticsPanel::setTools(const std::vector<ToolChoice>& tools, int current) {
  updating_ = true;
  tool_->clear();
  for (const ToolChoice& t : tools) {
    tool_->addItem(QString::fromStdString(t.label));
    QString tip = QString::fromStdString(t.mesh);
    if (!t.credit.empty()) tip += "\n" + QString::fromStdString(t.credit);
    tool_->setItemData(tool_->count() - 1, tip, Qt::ToolTipRole);
  }
  tool_->setCurrentIndex(current);
  updating_ = false;
}

int HapticsPanel::currentTool() const { return tool_->currentIndex(); }

void HapticsPanel::setPointShell(double spacing_m, std::size_t point_count) {
  updating_ = true;
  spacing_mm_->setValue(spacing_m * 1e3);
  updating_ = false;
  points_->setText(QString::number(static_cast<qulonglong>(point_count)));
}

double HapticsPanel::pointSpacing_m() const { return spacing_mm_->value() * 1e-3; }

void HapticsPanel::setBuilding(bool building) {
  if (building) points_->setText("building...");
  tool_->setEnabled(!building);
}

void HapticsPanel::setGains(const haptics::CouplingGains& gains) {
  updating_ = true;
  linear_->setValue(gains.linear_N_per_m);
  torsional_->setValue(gains.angular_Nm_per_rad);
  passivity_->setChecked(gains.passivity_control);
  updating_ = false;
}

haptics::CouplingGains HapticsPanel::gains() const {
  haptics::CouplingGains g;
  g.linear_N_per_m = linear_->value();
  g.angular_Nm_per_rad = torsional_->value();
  g.passivity_control = passivity_->isChecked();
  return g;
}

void HapticsPanel::setRunning(bool running, bool available) {
  running_ = running;
  start_stop_->setEnabled(available);
  start_stop_->setText(running ? "Stop haptics" : "Start haptics");
  start_stop_->setChecked(running);
}

void HapticsPanel::showSession(const runtime::Session& session, const std::vector<ToolChoice>& tools, int tool_index,
                               const QString& hardware_limits, bool replaying) {
  setRunning(session.hapticsRunning(), session.hapticThread() != nullptr && !replaying);
  setGains(session.gains());
  if (session.hasScene()) {
    setTools(tools, tool_index);
    const auto& tool = session.live().tool;
    setPointShell(session.live().pointSpacing_m(), tool != nullptr ? tool->point_shell.size() : std::size_t{0});
    updating_ = true;
    edge_test_->setChecked(session.live().tool_spec.edge_test);
    updating_ = false;
    showFeltGap(session);
  }
  QString name = "No device: haptics off";
  QString limits;
  if (const runtime::Device* device = session.device()) {
    name = QString::fromStdString(device->name());
    limits = hardware_limits;
    if (limits.isEmpty()) {
      if (session.simulatedDevice() != nullptr) limits = "Moved with the mouse and keys; its force is computed and shown, not felt.";
      const QString reported = deviceLimitsText(*device);
      if (!reported.isEmpty()) limits += (limits.isEmpty() ? "" : "\n") + reported;
    }
  }
  setDevice(name, limits);
}

void HapticsPanel::showFeltGap(const runtime::Session& session) {
  const auto& tool = session.live().tool;
  const bool edges = session.live().tool_spec.edge_test;
  if (tool == nullptr) {
    felt_gap_->setText("-");
    gap_tool_ = nullptr;
    return;
  }
  if (tool.get() == gap_tool_ && edges == gap_edges_) return;
  gap_tool_ = tool.get();
  gap_edges_ = edges;
  const haptics::ShellFidelity gap = runtime::feltGap(*tool, edges);
  const QString mm = QString::number(gap.max_gap_m * 1e3, 'f', 2) + " mm of the mesh";
  if (gap.max_gap_m > haptics::kShellGapWarning_m) {
    felt_gap_->setText(mm + ": too coarse for this tool's features; choose a finer spacing");
    felt_gap_->setStyleSheet("color: #b35900; font-weight: bold;");
  } else {
    felt_gap_->setText(mm);
    felt_gap_->setStyleSheet({});
  }
}

void HapticsPanel::setDevice(const QString& name, const QString& limits) {
  device_name_->setText(name);
  device_limits_->setText(limits);
  device_limits_->setVisible(!limits.isEmpty());
}

void HapticsPanel::setDeviceChoices(const QStringList& labels, int current, const QString& problems) {
  const QSignalBlocker block(device_choice_);
  device_choice_->clear();
  device_choice_->addItems(labels);
  device_choice_->setCurrentIndex(current);
  const QString tip = "The device that drives the tool: the simulated one or a connected haptic device";
  device_choice_->setToolTip(problems.isEmpty() ? tip : tip + "\n\nProblems while listing devices:\n" + problems);
  rescan_->setToolTip(problems.isEmpty() ? "List the connected devices again" : problems);
}

void HapticsPanel::setDeviceChoice(int index) {
  const QSignalBlocker block(device_choice_);
  device_choice_->setCurrentIndex(index);
}

}  // namespace vh::ui
