// The Segments dock's panel (see segments_panel.h).
#include "vh/ui/panels/segments_panel.h"

#include <cmath>

#include <QSignalBlocker>

#include <QCheckBox>
#include <QFormLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPixmap>
#include <QPushButton>
#include <QTableWidget>
#include <QVBoxLayout>

namespace vh::ui {
namespace {

QString q(const std::string& s) { return QString::fromStdString(s); }

QIcon swatch(const std::array<double, 3>& rgb) {
  QPixmap p(14, 14);
  p.fill(QColor::fromRgbF(static_cast<float>(rgb[0]), static_cast<float>(rgb[1]), static_cast<float>(rgb[2])));
  return QIcon(p);
}

}  // namespace

void SegmentsPanel::buildTable() {
  table_ = new QTableWidget(0, 7, this);
  table_->setHorizontalHeaderLabels({"Segment", "Felt", "Shown", "Critical", "Hardness", "Warn", "Alarm"});
  table_->horizontalHeaderItem(kFelt)->setToolTip("Feel this segment's surface instead of the scan's isosurface");
  table_->horizontalHeaderItem(kShown)->setToolTip("Draw this segment as a coloured surface beside the scan");
  table_->horizontalHeaderItem(kCritical)->setToolTip(
      "Alert (and record an event) when the tool touches it, and warn as the tool comes near it");
  table_->horizontalHeaderItem(kHardness)->setToolTip(
      "Drilling: the energy to remove 1 mm^3 [J/mm^3] (double-click to edit); empty: from the segment's HU "
      "(cortical bone 2.0, cancellous 0.6, soft tissue 0.1)");
  table_->horizontalHeaderItem(kWarn)->setToolTip(
      "Warn [mm]: for a critical segment, warn (amber tool, status, a cue beeping faster as you near it) within "
      "this distance of the tool's surface, at most 20 (double-click to edit)");
  table_->horizontalHeaderItem(kAlarm)->setToolTip(
      "Alarm [mm]: for a critical segment, alarm (red tool) within this distance, at most the warning distance");
  table_->horizontalHeader()->setSectionResizeMode(kName, QHeaderView::Stretch);
  for (int c = kFelt; c <= kAlarm; ++c) table_->horizontalHeader()->setSectionResizeMode(c, QHeaderView::ResizeToContents);
  table_->verticalHeader()->hide();
  table_->setSelectionMode(QAbstractItemView::NoSelection);
  // Hardness and the distances only.
  table_->setEditTriggers(QAbstractItemView::DoubleClicked | QAbstractItemView::EditKeyPressed);
}

bool SegmentsPanel::takeThreshold(QTableWidgetItem* item) {
  const int r = item->row();
  QTableWidgetItem* warn = table_->item(r, kWarn);
  QTableWidgetItem* alarm = table_->item(r, kAlarm);
  bool ok_warn = false, ok_alarm = false;
  const double warn_mm = warn != nullptr ? warn->text().trimmed().toDouble(&ok_warn) : 0.0;
  const double alarm_mm = alarm != nullptr ? alarm->text().trimmed().toDouble(&ok_alarm) : 0.0;
  const bool taken = ok_warn && ok_alarm && alarm_mm > 0.0 && alarm_mm <= warn_mm &&
                     warn_mm <= runtime::kProximityRange_m * 1e3;
  const QSignalBlocker block(table_);
  if (!taken) {
    item->setText(item->data(Qt::UserRole).toString());  // refused: back to what it was
    return false;
  }
  item->setData(Qt::UserRole, item->text());
  return true;
}

SegmentsPanel::SegmentsPanel(QWidget* parent) : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  open_ = new QPushButton("Open Segmentation...", this);
  open_->setToolTip("A 3D Slicer segmentation (.seg.nrrd) or a label-map NRRD on the open scan's patient frame");
  source_ = new QLabel(this);
  source_->setWordWrap(true);
  buildTable();
  auto* form = new QFormLayout;
  smoothing_ = new RangeSpinBox("the smoothing", this);
  smoothing_->setRange(0.0, 3.0);
  smoothing_->setSingleStep(0.25);
  smoothing_->setValue(1.0);
  smoothing_->setSuffix(" voxel");
  smoothing_->setToolTip("Gaussian sigma of the felt surface: 0 keeps the voxels' steps; 1 smooths them "
                         "and stays within about half a voxel of the segment");
  form->addRow("Smoothing:", smoothing_);
  through_scan_ = new QCheckBox("Show segments through the scan", this);
  through_scan_->setObjectName("segmentsThroughScan");
  through_scan_->setToolTip("A segment inside the body is hidden by the scan's surface: draw the shown segments in "
                            "front of it (the tool stays in front of the segments where it is nearer)");
  sound_ = new QCheckBox("Alert sounds (critical segment near or touched, technique)", this);
  sound_->setToolTip("Beep when a critical segment is touched or a technique rule fires, and beep faster and "
                     "faster while the tool is within a critical segment's warning distance");
  burr_sound_ = new QCheckBox("Burr sound", this);
  burr_sound_->setToolTip("Play the drilling burr's sound: its pitch falls as you push and with the hardness "
                          "of what it cuts, it grows louder with the volume removed per second");
  touched_ = new QLabel("Touching: nothing", this);
  touched_->setWordWrap(true);
  layout->addWidget(open_);
  layout->addWidget(source_);
  layout->addWidget(table_, 1);
  layout->addLayout(form);
  layout->addWidget(through_scan_);
  layout->addWidget(sound_);
  layout->addWidget(burr_sound_);
  connect(burr_sound_, &QCheckBox::toggled, this, &SegmentsPanel::burrSoundToggled);
  connect(sound_, &QCheckBox::toggled, this, &SegmentsPanel::alertSoundToggled);
  layout->addWidget(touched_);

  connect(table_, &QTableWidget::cellDoubleClicked, this, [this](int row, int column) {
    if (column == kName) emit goToSegmentRequested(row);
  });
  connect(table_, &QTableWidget::itemChanged, this, [this](QTableWidgetItem* item) {
    if (filling_) return;
    if (item != nullptr && item->column() == kHardness) {
      bool ok = false;
      const double e = item->text().trimmed().toDouble(&ok);
      if (ok && e > 0.0 && std::isfinite(e)) {
        emit hardnessChanged(item->row(), e);
      } else {
        const QSignalBlocker block(table_);
        item->setText(item->data(Qt::UserRole).toString());  // refused: back to what it was
      }
      return;
    }
    if (item != nullptr && (item->column() == kWarn || item->column() == kAlarm)) {
      if (takeThreshold(item)) emit choicesChanged(choices());
      return;
    }
    emit choicesChanged(choices());
  });
  connect(smoothing_, &QAbstractSpinBox::editingFinished, this, [this] {
    if (!filling_) emit choicesChanged(choices());
  });
  connect(through_scan_, &QCheckBox::toggled, this, &SegmentsPanel::throughScanToggled);
  connect(open_, &QPushButton::clicked, this, &SegmentsPanel::openRequested);
  showSegments(nullptr);
}

void SegmentsPanel::showSegments(const runtime::SegmentSet* set) {
  filling_ = true;
  table_->setRowCount(0);
  names_.clear();
  ids_.clear();
  critical_.clear();
  if (set == nullptr) {
    source_->setText("No segmentation. Open a 3D Slicer segmentation (.seg.nrrd) or a label map to feel and "
                     "show its segments.");
    table_->setEnabled(false);
    smoothing_->setEnabled(false);
    filling_ = false;
    setTouched(-1);
    return;
  }
  const auto& seg = set->segmentation();
  source_->setText(QString("%1: %2 segment(s)%3")
                       .arg(q(seg.source.filename().string()))
                       .arg(seg.segments.size())
                       .arg(set->felt().empty() ? QString("; the scan's isosurface is felt")
                                                : QString("; the felt segments replace the scan's isosurface")));
  table_->setEnabled(true);
  smoothing_->setEnabled(true);
  smoothing_->setValue(set->smoothingVoxels());
  table_->setRowCount(static_cast<int>(seg.segments.size()));
  for (int s = 0; s < static_cast<int>(seg.segments.size()); ++s) {
    const io::SegmentInfo& info = seg.segments[static_cast<std::size_t>(s)];
    auto* name = new QTableWidgetItem(swatch(info.color_rgb), q(info.name));
    name->setFlags(name->flags() & ~Qt::ItemIsEditable);
    name->setToolTip(QString("%1, label %2, layer %3, %4 voxels; double-click to frame it in the view")
                         .arg(q(info.id))
                         .arg(info.label_value)
                         .arg(info.layer)
                         .arg(static_cast<qulonglong>(info.voxel_count)));
    table_->setItem(s, kName, name);
    const auto check = [&](Column c, bool on) {
      auto* item = new QTableWidgetItem;
      item->setFlags(Qt::ItemIsUserCheckable | Qt::ItemIsEnabled);
      item->setCheckState(on ? Qt::Checked : Qt::Unchecked);
      table_->setItem(s, c, item);
    };
    check(kFelt, set->isFelt(s));
    check(kShown, set->isShown(s));
    check(kCritical, set->isCritical(s));
    auto* hardness = new QTableWidgetItem;
    hardness->setFlags(Qt::ItemIsEnabled | Qt::ItemIsEditable);
    hardness->setToolTip("J/mm^3; empty: from the segment's HU");
    table_->setItem(s, kHardness, hardness);
    const runtime::ProximityThresholds& t = set->thresholds(s);
    for (const auto& [column, mm] : {std::pair{kWarn, t.warn_m * 1e3}, std::pair{kAlarm, t.alarm_m * 1e3}}) {
      auto* cell = new QTableWidgetItem(QString::number(mm, 'g', 3));
      cell->setFlags(Qt::ItemIsEnabled | Qt::ItemIsEditable);
      cell->setData(Qt::UserRole, cell->text());
      table_->setItem(s, column, cell);
    }
    names_.push_back(q(info.name));
    ids_.push_back(q(info.id));
    critical_.push_back(set->isCritical(s));
  }
  filling_ = false;
  setTouched(touched_segment_);
}

void SegmentsPanel::showHardness(const std::map<std::string, double>& hardness) {
  filling_ = true;
  const auto lower = [](QString t) { return t.toLower(); };
  for (int r = 0; r < table_->rowCount() && static_cast<std::size_t>(r) < names_.size(); ++r) {
    QTableWidgetItem* item = table_->item(r, kHardness);
    if (item == nullptr) continue;
    QString text;
    for (const auto& [key, e] : hardness)
      if (lower(q(key)) == lower(names_[static_cast<std::size_t>(r)]) || lower(q(key)) == lower(ids_[static_cast<std::size_t>(r)]))
        text = QString::number(e, 'g', 4);
    item->setText(text);
    item->setData(Qt::UserRole, text);
  }
  filling_ = false;
}

void SegmentsPanel::setDisplayColour(int segment, const std::array<double, 3>& rgb) {
  QTableWidgetItem* item = segment >= 0 && segment < table_->rowCount() ? table_->item(segment, kName) : nullptr;
  if (item == nullptr) return;
  const QSignalBlocker block(table_);
  item->setIcon(swatch(rgb));
}

void SegmentsPanel::setTouched(int segment) {
  touched_segment_ = segment;
  for (int r = 0; r < table_->rowCount(); ++r) {
    if (QTableWidgetItem* item = table_->item(r, kName)) {
      QFont f = item->font();
      f.setBold(r == segment);
      const QSignalBlocker block(table_);
      item->setFont(f);
    }
  }
  if (segment < 0 || static_cast<std::size_t>(segment) >= names_.size()) {
    touched_->setText("Touching: nothing");
    touched_->setStyleSheet({});
    return;
  }
  const bool critical = critical_[static_cast<std::size_t>(segment)];
  touched_->setText("Touching: " + names_[static_cast<std::size_t>(segment)] + (critical ? " (CRITICAL)" : ""));
  touched_->setStyleSheet(critical ? "color: white; background: #c0392b; font-weight: bold; padding: 2px;" : "");
}

SegmentChoices SegmentsPanel::choices() const {
  SegmentChoices c;
  c.smoothing_voxels = smoothing_->value();
  for (int r = 0; r < table_->rowCount(); ++r) {
    const auto on = [&](Column col) {
      const QTableWidgetItem* item = table_->item(r, col);
      return item != nullptr && item->checkState() == Qt::Checked;
    };
    if (on(kFelt)) c.felt.push_back(r);
    if (on(kShown)) c.shown.push_back(r);
    if (on(kCritical)) c.critical.push_back(r);
    const auto mm = [&](Column col) {
      const QTableWidgetItem* item = table_->item(r, col);
      return item != nullptr ? item->data(Qt::UserRole).toString().toDouble() * 1e-3 : 0.0;
    };
    c.thresholds.push_back({mm(kWarn), mm(kAlarm)});
  }
  return c;
}

bool SegmentsPanel::alertSound() const { return sound_->isChecked(); }
bool SegmentsPanel::burrSound() const { return burr_sound_->isChecked(); }

void SegmentsPanel::setThroughScan(bool on) {
  const QSignalBlocker block(through_scan_);
  through_scan_->setChecked(on);
}

bool SegmentsPanel::throughScan() const { return through_scan_->isChecked(); }

void SegmentsPanel::setSounds(bool burr, bool alert) {
  const QSignalBlocker block_burr(burr_sound_), block_alert(sound_);
  burr_sound_->setChecked(burr);
  sound_->setChecked(alert);
}

}  // namespace vh::ui
