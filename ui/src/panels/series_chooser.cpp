#include "vh/ui/panels/series_chooser.h"

#include <QDialogButtonBox>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QItemSelectionModel>
#include <QLabel>
#include <QPushButton>
#include <QTableView>
#include <QVBoxLayout>

namespace vh::ui {
namespace {

QString utf8(const std::string& s) { return QString::fromStdString(s); }

/// "Doe^John" -> "Doe, John".
QString personName(const std::string& dicom) {
  QStringList parts = utf8(dicom).split('^', Qt::KeepEmptyParts);
  while (!parts.isEmpty() && parts.last().trimmed().isEmpty()) parts.removeLast();
  if (parts.size() >= 2) return parts[0].trimmed() + ", " + parts.mid(1).join(' ').simplified();
  return parts.join(' ').simplified();
}

/// "20110516" -> "2011-05-16".
QString isoDate(const std::string& da) {
  const QString d = utf8(da);
  if (d.size() == 8) return d.left(4) + '-' + d.mid(4, 2) + '-' + d.mid(6, 2);
  return d;
}

QString number(double v) { return QString::number(v, 'f', v >= 10.0 ? 1 : 2); }

}  // namespace

int estimatedTimePoints(const io::DicomSeriesInfo& series) {
  if (series.slice_count <= 0 || series.file_count <= series.slice_count) return 1;
  return series.file_count % series.slice_count == 0 ? series.file_count / series.slice_count : 1;
}

DicomSeriesModel::DicomSeriesModel(std::vector<io::DicomSeriesInfo> series, QObject* parent)
    : QAbstractTableModel(parent), series_(std::move(series)) {}

int DicomSeriesModel::rowCount(const QModelIndex& parent) const {
  return parent.isValid() ? 0 : static_cast<int>(series_.size());
}

int DicomSeriesModel::columnCount(const QModelIndex& parent) const { return parent.isValid() ? 0 : kColumnCount; }

QVariant DicomSeriesModel::data(const QModelIndex& index, int role) const {
  if (!index.isValid() || index.row() < 0 || index.row() >= rowCount()) return {};
  const io::DicomSeriesInfo& s = series_[static_cast<std::size_t>(index.row())];
  if (role == Qt::UserRole) return s.index;
  if (role == Qt::TextAlignmentRole) {
    return index.column() == kSlices ? QVariant(Qt::AlignRight | Qt::AlignVCenter) : QVariant();
  }
  if (role == Qt::ToolTipRole) {  // the whole row, uncut: descriptions are often longer than their column
    const QString folder = s.files.empty() ? utf8(s.folder.string()) : utf8(s.files.front().parent_path().string());
    QString tip;
    for (const int c : {kSeries, kStudy, kPatient}) {
      const QString text = data(this->index(index.row(), c), Qt::DisplayRole).toString();
      if (!text.isEmpty()) tip += headerData(c, Qt::Horizontal, Qt::DisplayRole).toString() + ": " + text + "\n";
    }
    return tip + QString("%1 files in %2\nSeries UID %3").arg(s.file_count).arg(folder, utf8(s.series_uid));
  }
  if (role != Qt::DisplayRole) return {};
  switch (index.column()) {
    case kPatient: {
      QString text = personName(s.patient_name);
      if (!s.patient_id.empty()) text += (text.isEmpty() ? "" : " ") + QString("(%1)").arg(utf8(s.patient_id));
      return text;
    }
    case kStudy: {
      QString text = utf8(s.study_description);
      const QString date = isoDate(s.study_date);
      if (!date.isEmpty()) text += (text.isEmpty() ? "" : " ") + QString("[%1]").arg(date);
      return text;
    }
    case kSeries: {
      QString text = utf8(s.series_description);
      if (s.series_number > 0) text = QString("#%1 ").arg(s.series_number) + text;
      return text.trimmed();
    }
    case kModality: return utf8(s.modality);
    case kSlices: return s.slice_count;
    case kSpacing:
      if (s.spacing_mm.x() <= 0.0) return QString("?");
      if (s.spacing_mm.z() <= 0.0) {
        return QString("%1 x %2 mm").arg(number(s.spacing_mm.x()), number(s.spacing_mm.y()));
      }
      return QString("%1 x %2 x %3 mm").arg(number(s.spacing_mm.x()), number(s.spacing_mm.y()), number(s.spacing_mm.z()));
    case kMatrix:
      if (s.columns <= 0) return QString("?");
      return QString("%1 x %2").arg(s.columns).arg(s.rows);
    default: return {};
  }
}

QVariant DicomSeriesModel::headerData(int section, Qt::Orientation orientation, int role) const {
  if (orientation != Qt::Horizontal || role != Qt::DisplayRole) return QAbstractTableModel::headerData(section, orientation, role);
  switch (section) {
    case kPatient: return QString("Patient");
    case kStudy: return QString("Study");
    case kSeries: return QString("Series");
    case kModality: return QString("Modality");
    case kSlices: return QString("Slices");
    case kSpacing: return QString("Spacing");
    case kMatrix: return QString("Matrix");
    default: return {};
  }
}

int DicomSeriesModel::largestRow() const {
  int best = -1;
  for (int r = 0; r < rowCount(); ++r) {
    if (best < 0 || series_[static_cast<std::size_t>(r)].slice_count > series_[static_cast<std::size_t>(best)].slice_count) {
      best = r;
    }
  }
  return best;
}

SeriesChooserDialog::SeriesChooserDialog(const QString& folder, std::vector<io::DicomSeriesInfo> series, QWidget* parent)
    : QDialog(parent),
      model_(new DicomSeriesModel(std::move(series), this)),
      table_(new QTableView(this)),
      phase_(new RangeIntSpinBox("the time point", this)) {
  setWindowTitle("Choose a DICOM series");
  auto* layout = new QVBoxLayout(this);
  auto* text = new QLabel(QString("<b>%1</b> holds %2 image series. Choose the one to open:")
                              .arg(folder.toHtmlEscaped())
                              .arg(model_->rowCount()),
                          this);
  text->setWordWrap(true);
  layout->addWidget(text);
  table_->setObjectName("seriesTable");
  table_->setModel(model_);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->verticalHeader()->hide();
  table_->horizontalHeader()->setStretchLastSection(false);
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  table_->horizontalHeader()->setSectionResizeMode(DicomSeriesModel::kSeries, QHeaderView::Stretch);
  // Study and patient are the same for most rows of a folder: narrow, the user widens them.
  for (const int c : {DicomSeriesModel::kStudy, DicomSeriesModel::kPatient}) {
    table_->horizontalHeader()->setSectionResizeMode(c, QHeaderView::Interactive);
    table_->setColumnWidth(c, 140);
  }
  table_->setTextElideMode(Qt::ElideMiddle);
  table_->setAlternatingRowColors(true);
  table_->setWordWrap(false);
  layout->addWidget(table_, 1);
  auto* phase_row = new QHBoxLayout();
  auto* phase_label = new QLabel("Time point (4-D series):", this);
  phase_->setObjectName("seriesPhase");
  phase_->setToolTip("Cardiac phase, dynamic frame or echo to load, from 1 (4-D series only)");
  phase_label->setBuddy(phase_);
  phase_row->addWidget(phase_label);
  phase_row->addWidget(phase_);
  auto* phase_count = new QLabel(this);
  phase_row->addWidget(phase_count);
  phase_row->addStretch(1);
  layout->addLayout(phase_row);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Open | QDialogButtonBox::Cancel, this);
  layout->addWidget(buttons);
  connect(buttons, &QDialogButtonBox::accepted, this, unlessRefused(*this, {phase_}, [this] { accept(); }));
  connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
  connect(table_, &QTableView::doubleClicked, this, &QDialog::accept);
  connect(table_->selectionModel(), &QItemSelectionModel::selectionChanged, this, [this, phase_count] {
    const int row = selectedRow();
    const int n = row < 0 ? 1 : estimatedTimePoints(model_->series(row));
    phase_->setRange(1, n);
    phase_->setEnabled(n > 1);
    phase_count->setText(n > 1 ? QString("of %1").arg(n) : QString("(3-D series)"));
  });
  phase_->setRange(1, 1);
  phase_->setEnabled(false);
  selectRow(model_->largestRow());
  resize(980, 340);
}

int SeriesChooserDialog::selectedRow() const {
  const QModelIndexList rows = table_->selectionModel()->selectedRows();
  return rows.isEmpty() ? -1 : rows.front().row();
}

int SeriesChooserDialog::selectedPhase() const { return phase_->isEnabled() ? phase_->value() - 1 : 0; }

void SeriesChooserDialog::selectRow(int row) {
  if (row >= 0 && row < model_->rowCount()) table_->selectRow(row);
}

}  // namespace vh::ui
