#pragma once
/// @file
/// Choosing one DICOM series of a folder: a table model over io::DicomSeriesInfo (patient,
/// study, series description, modality, slice count, voxel spacing, matrix size) and the modal
/// dialog around it, with the time point to load of a 4-D series. The largest series is
/// preselected (what loadVolume() would take).

#include <vector>

#include <QAbstractTableModel>
#include <QDialog>

#include "vh/io/dicom_series.h"
#include "vh/ui/panels/range_spin_box.h"

class QTableView;

namespace vh::ui {

/// Time points (cardiac phases, dynamic frames, echoes) a listed series seems to hold: its
/// files over the slices of one volume when that divides evenly (2-D files), else 1 (a
/// multi-frame file's time points are known only once loaded: io::VolumeInfo::phase_count).
int estimatedTimePoints(const io::DicomSeriesInfo& series);

class DicomSeriesModel : public QAbstractTableModel {
  Q_OBJECT

 public:
  /// What tells series apart comes first (modality, slices, spacing), then the description
  /// (cut to the column; whole in the row's tooltip), the matrix, the study and the patient.
  enum Column {
    kModality,
    kSlices,
    kSpacing,
    kSeries,
    kMatrix,
    kStudy,
    kPatient,
    kColumnCount
  };

  explicit DicomSeriesModel(std::vector<io::DicomSeriesInfo> series, QObject* parent = nullptr);

  int rowCount(const QModelIndex& parent = {}) const override;
  int columnCount(const QModelIndex& parent = {}) const override;
  /// DisplayRole: text ("0.45 x 0.45 x 1.00 mm", "512 x 512"); ToolTipRole: the folder of the
  /// files and the series UID; Qt::UserRole: the series' index in the folder scan;
  /// Qt::TextAlignmentRole: numbers right-aligned.
  QVariant data(const QModelIndex& index, int role = Qt::DisplayRole) const override;
  QVariant headerData(int section, Qt::Orientation orientation, int role = Qt::DisplayRole) const override;

  const io::DicomSeriesInfo& series(int row) const { return series_.at(static_cast<std::size_t>(row)); }
  /// Row of the series with the most slices (ties: the first); -1 when empty.
  int largestRow() const;

 private:
  std::vector<io::DicomSeriesInfo> series_;
};

class SeriesChooserDialog : public QDialog {
  Q_OBJECT

 public:
  /// @param folder shown in the dialog's text.
  SeriesChooserDialog(const QString& folder, std::vector<io::DicomSeriesInfo> series, QWidget* parent = nullptr);

  /// The selected row (-1 when none); selected series via model()->series(row).
  int selectedRow() const;
  void selectRow(int row);
  /// The time point to load, 0-based (runtime::VolumeSpec::phase); 0 unless the selected series
  /// is 4-D (estimatedTimePoints() > 1).
  int selectedPhase() const;
  /// The time point chooser (1-based, as shown); enabled for a 4-D series.
  RangeIntSpinBox* phaseSpinBox() const noexcept { return phase_; }
  DicomSeriesModel* model() const noexcept { return model_; }
  QTableView* table() const noexcept { return table_; }

 private:
  DicomSeriesModel* model_;
  QTableView* table_;
  RangeIntSpinBox* phase_;
};

}  // namespace vh::ui
