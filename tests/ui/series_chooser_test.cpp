// Listing the DICOM series of a folder (io/dicom_series.h), loading a chosen one, and the series
// chooser's model and dialog (ui/series_chooser.h).
#include "vh/ui/panels/series_chooser.h"

#include <filesystem>

#include <QApplication>
#include <QItemSelectionModel>
#include <QTableView>
#include <QTemporaryDir>

#include <gtest/gtest.h>
#include <vtkImageData.h>

#include "ui_test_util.h"
#include "vh/io/dicom_series.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using test::kHead;
using test::kSharedData;

const fs::path kPhantom = kSharedData / "ct/philips-head-phantom-bone";

io::DicomSeriesInfo series(const char* description, int slices, const char* modality = "CT") {
  io::DicomSeriesInfo s;
  s.folder = "/data/study";
  s.patient_name = "Doe^Jane";
  s.patient_id = "123";
  s.study_description = "HEAD";
  s.study_date = "20110516";
  s.series_description = description;
  s.series_number = 3;
  s.modality = modality;
  s.file_count = slices;
  s.slice_count = slices;
  s.rows = 512;
  s.columns = 512;
  s.spacing_mm = Eigen::Vector3d(0.451, 0.451, 1.0);
  return s;
}

TEST(DicomSeriesModel, ShowsPatientStudySeriesModalitySlicesAndSpacing) {
  DicomSeriesModel model({series("Scout", 2), series("BONE 1mm", 140), series("SOFT", 70, "CT")});
  ASSERT_EQ(model.rowCount(), 3);
  ASSERT_EQ(model.columnCount(), DicomSeriesModel::kColumnCount);
  auto text = [&](int row, int column) { return model.data(model.index(row, column)).toString(); };
  EXPECT_EQ(text(1, DicomSeriesModel::kPatient), "Doe, Jane (123)");
  EXPECT_EQ(text(1, DicomSeriesModel::kStudy), "HEAD [2011-05-16]");
  EXPECT_EQ(text(1, DicomSeriesModel::kSeries), "#3 BONE 1mm");
  EXPECT_EQ(text(1, DicomSeriesModel::kModality), "CT");
  EXPECT_EQ(model.data(model.index(1, DicomSeriesModel::kSlices)).toInt(), 140);
  EXPECT_EQ(text(1, DicomSeriesModel::kSpacing), "0.45 x 0.45 x 1.00 mm");
  EXPECT_EQ(text(1, DicomSeriesModel::kMatrix), "512 x 512");
  EXPECT_EQ(model.headerData(DicomSeriesModel::kSlices, Qt::Horizontal).toString(), "Slices");
  EXPECT_EQ(model.largestRow(), 1);
  EXPECT_FALSE(model.data(model.index(7, 0)).isValid());

  SeriesChooserDialog dialog("/data/study", {series("Scout", 2), series("BONE 1mm", 140)});
  EXPECT_EQ(dialog.selectedRow(), 1) << "the largest series is preselected";
  dialog.selectRow(0);
  EXPECT_EQ(dialog.selectedRow(), 0);
  EXPECT_EQ(dialog.model()->series(dialog.selectedRow()).series_description, "Scout");
}

TEST(DicomSeriesModel, ModalitySlicesAndSpacingShowFirstAndTheWholeDescriptionOnHover) {
  const std::string long_description =
      "mocoMEAN_ep2d_bold_moco_TR2000_3mm_iso_resting_state_with_a_very_long_protocol_name";
  io::DicomSeriesInfo s = series(long_description.c_str(), 36, "MR");
  s.patient_name = "Doe^Jane^With^A^Long^Name";
  s.study_description = "Functional MRI of the brain, research protocol, long study description";
  SeriesChooserDialog dialog("/data/study", {s, series("Scout", 2)});
  dialog.resize(640, 300);  // a small screen's dialog
  dialog.show();
  auto* table = dialog.findChild<QTableView*>("seriesTable");
  ASSERT_NE(table, nullptr);
  QApplication::processEvents();
  // The columns that tell series apart lie wholly inside the visible part of the table, in
  // this order, on the left.
  const int visible_px = table->viewport()->width();
  int left_px = -1;
  for (const int c : {DicomSeriesModel::kModality, DicomSeriesModel::kSlices, DicomSeriesModel::kSpacing}) {
    const int x = table->columnViewportPosition(c);
    EXPECT_GT(x, left_px) << "column " << c;
    EXPECT_LE(x + table->columnWidth(c), visible_px) << "column " << c << " off-screen";
    left_px = x;
  }
  EXPECT_LT(table->columnViewportPosition(DicomSeriesModel::kModality),
            table->columnViewportPosition(DicomSeriesModel::kSeries));
  // The description, cut in its column, is whole in every cell's tooltip, with study and patient.
  const QString tip = dialog.model()->data(dialog.model()->index(0, DicomSeriesModel::kModality), Qt::ToolTipRole).toString();
  EXPECT_TRUE(tip.contains(QString::fromStdString(long_description))) << tip.toStdString();
  EXPECT_TRUE(tip.contains("Functional MRI of the brain, research protocol, long study description")) << tip.toStdString();
  EXPECT_TRUE(tip.contains("Doe, Jane")) << tip.toStdString();
}

TEST(DicomSeries, ListsTheSmallHeadAsOneCtSeries) {
  if (!fs::exists(kHead)) GTEST_SKIP() << "dataset absent: " << kHead;
  int calls = 0;
  const auto list = io::listDicomSeries(kHead, [&](int, int) { ++calls; });
  ASSERT_EQ(list.size(), 1u);
  const io::DicomSeriesInfo& s = list.front();
  EXPECT_EQ(s.modality, "CT");
  EXPECT_EQ(s.file_count, 93);
  EXPECT_EQ(s.slice_count, 93);
  EXPECT_EQ(s.columns, 64);
  EXPECT_EQ(s.rows, 64);
  EXPECT_NEAR(s.spacing_mm.x(), 3.2, 1e-3);
  EXPECT_NEAR(s.spacing_mm.z(), 1.5, 1e-3);
  EXPECT_GE(calls, 2) << "progress reported";
  const io::LoadedVolume v = io::loadDicomSeries(kHead, 0);
  int dims[3];
  v.image->GetDimensions(dims);
  EXPECT_EQ(dims[0] * dims[1] * dims[2], 64 * 64 * 93);
  EXPECT_THROW(io::loadDicomSeries(kHead, 1), io::LoadError);
}

TEST(DicomSeries, AFolderWithTwoSeriesListsBothAndLoadsTheChosenOne) {
  if (!fs::exists(kHead) || !fs::exists(kPhantom)) GTEST_SKIP() << "datasets absent";
  QTemporaryDir tmp;
  const fs::path root = tmp.path().toStdString();
  fs::create_directories(root / "head");
  fs::create_directories(root / "phantom");
  for (const auto& e : fs::directory_iterator(kHead)) fs::copy_file(e.path(), root / "head" / e.path().filename());
  for (const char* name : {"I10", "I20", "I30"}) fs::copy_file(kPhantom / name, root / "phantom" / name);
  const auto list = io::listDicomSeries(root);
  ASSERT_EQ(list.size(), 2u);
  int head = -1, phantom = -1;
  for (const auto& s : list) {
    if (s.file_count == 93) head = s.index;
    if (s.file_count == 3) phantom = s.index;
  }
  ASSERT_GE(head, 0);
  ASSERT_GE(phantom, 0);
  EXPECT_EQ(list[static_cast<std::size_t>(phantom)].columns, 512);
  DicomSeriesModel model(list);
  EXPECT_EQ(model.data(model.index(model.largestRow(), DicomSeriesModel::kSlices)).toInt(), 93);
  const io::LoadedVolume v = io::loadDicomSeries(list[static_cast<std::size_t>(phantom)]);
  int dims[3];
  v.image->GetDimensions(dims);
  EXPECT_EQ(dims[0], 512);
  EXPECT_EQ(dims[2], 3) << "only the chosen series is read";
}

TEST(DicomSeries, ErrorsNameTheFolder) {
  QTemporaryDir tmp;
  try {
    io::listDicomSeries(tmp.path().toStdString());
    FAIL() << "an empty folder has no series";
  } catch (const io::LoadError& e) {
    EXPECT_NE(std::string(e.what()).find(tmp.path().toStdString()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no DICOM image series"), std::string::npos) << e.what();
  }
  EXPECT_THROW(io::listDicomSeries(tmp.filePath("missing").toStdString()), io::LoadError);
}

}  // namespace
}  // namespace vh::ui
