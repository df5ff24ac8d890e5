// Listing the DICOM series of a folder and loading one of them (see dicom_series.h).
#include "vh/io/dicom_series.h"

#include <algorithm>
#include <cmath>
#include <system_error>

#include <vtkDICOMDictHash.h>
#include <vtkDICOMDirectory.h>
#include <vtkDICOMItem.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMReader.h>
#include <vtkDICOMSliceSorter.h>
#include <vtkDICOMValue.h>
#include <vtkInformation.h>
#include <vtkSmartPointer.h>
#include <vtkStreamingDemandDrivenPipeline.h>
#include <vtkStringArray.h>

#include "loader_internal.h"
#include "vtk_error_capture.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;

std::string text(const vtkDICOMItem& item, vtkDICOMTag tag) {
  const vtkDICOMValue& v = item.Get(tag);
  return v.IsValid() ? detail::trim(v.AsUTF8String()) : std::string();
}

int integer(const vtkDICOMItem& item, vtkDICOMTag tag) {
  const vtkDICOMValue& v = item.Get(tag);
  return v.IsValid() && v.GetNumberOfValues() > 0 ? v.AsInt() : 0;
}

/// The scan every function here shares with loadDicom(): kDicomScanDepth levels, DICOMDIR ignored,
/// images only.
vtkSmartPointer<vtkDICOMDirectory> scanFolder(const fs::path& folder, detail::VtkErrorCapture& capture) {
  std::error_code ec;
  if (folder.empty()) throw LoadError("(empty path): no folder given");
  if (!fs::exists(folder, ec)) detail::fail(folder, "no such folder");
  if (!fs::is_directory(folder, ec)) detail::fail(folder, "not a folder (a DICOM series is opened by its folder)");
  auto directory = vtkSmartPointer<vtkDICOMDirectory>::New();
  capture.watch(directory);
  directory->SetDirectoryName(folder.string().c_str());
  directory->SetScanDepth(detail::kDicomScanDepth);
  directory->IgnoreDicomdirOn();
  directory->RequirePixelDataOn();
  directory->Update();
  if (directory->GetNumberOfSeries() == 0) {
    const std::string vtk = capture.hasErrors() ? " (" + capture.firstError() + ")" : "";
    detail::fail(folder, "no DICOM image series found in the folder" + vtk);
  }
  return directory;
}

/// Rows, columns, slices and voxel size of a series from its headers (no pixel data read).
/// Leaves the fields at zero when the headers do not make one volume.
void readGeometry(const vtkSmartPointer<vtkStringArray>& files, DicomSeriesInfo& info) {
  detail::VtkErrorCapture capture;
  auto reader = vtkSmartPointer<vtkDICOMReader>::New();
  capture.watch(reader);
  capture.watch(reader->GetSorter());
  reader->SetFileNames(files);
  reader->SortingOn();
  reader->TimeAsVectorOff();
  reader->SetDesiredTimeIndex(0);
  reader->UpdateInformation();
  if (capture.hasErrors()) return;
  vtkInformation* out = reader->GetOutputInformation(0);
  if (out == nullptr || !out->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT())) return;
  int extent[6];
  out->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), extent);
  info.columns = extent[1] - extent[0] + 1;
  info.rows = extent[3] - extent[2] + 1;
  info.slice_count = extent[5] - extent[4] + 1;
  double spacing[3] = {0.0, 0.0, 0.0};
  if (out->Has(vtkDataObject::SPACING())) out->Get(vtkDataObject::SPACING(), spacing);
  info.spacing_mm = Eigen::Vector3d(std::abs(spacing[0]), std::abs(spacing[1]),
                                    info.slice_count > 1 ? std::abs(spacing[2]) : 0.0);
}

}  // namespace

namespace detail {

std::vector<DicomSeriesInfo> listDicomSeriesInProcess(const fs::path& folder,
                                                      const std::function<void(int, int)>& progress,
                                                      const std::atomic<bool>* cancel) {
  detail::VtkErrorCapture capture;
  const vtkSmartPointer<vtkDICOMDirectory> directory = scanFolder(folder, capture);
  const int n_series = directory->GetNumberOfSeries();
  std::vector<DicomSeriesInfo> out(static_cast<std::size_t>(n_series));
  for (int s = 0; s < n_series; ++s) {
    out[static_cast<std::size_t>(s)].folder = folder;
    out[static_cast<std::size_t>(s)].index = s;
  }
  // Patient and study records are per study; series are numbered consecutively within one.
  for (int study = 0; study < directory->GetNumberOfStudies(); ++study) {
    const vtkDICOMItem& patient = directory->GetPatientRecordForStudy(study);
    const vtkDICOMItem& record = directory->GetStudyRecord(study);
    for (int s = directory->GetFirstSeriesForStudy(study); s <= directory->GetLastSeriesForStudy(study); ++s) {
      if (s < 0 || s >= n_series) continue;
      DicomSeriesInfo& info = out[static_cast<std::size_t>(s)];
      info.patient_name = text(patient, DC::PatientName);
      info.patient_id = text(patient, DC::PatientID);
      info.study_description = text(record, DC::StudyDescription);
      info.study_date = text(record, DC::StudyDate);
    }
  }
  if (progress) progress(0, n_series);
  for (int s = 0; s < n_series; ++s) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
      out.resize(static_cast<std::size_t>(s));
      break;
    }
    DicomSeriesInfo& info = out[static_cast<std::size_t>(s)];
    const vtkDICOMItem& series = directory->GetSeriesRecord(s);
    info.series_description = text(series, DC::SeriesDescription);
    info.series_uid = text(series, DC::SeriesInstanceUID);
    info.series_number = integer(series, DC::SeriesNumber);
    info.modality = text(series, DC::Modality);
    vtkStringArray* names = directory->GetFileNamesForSeries(s);
    info.file_count = static_cast<int>(names->GetNumberOfValues());
    info.files.reserve(static_cast<std::size_t>(info.file_count));
    for (vtkIdType f = 0; f < names->GetNumberOfValues(); ++f) {
      info.files.emplace_back(std::string(names->GetValue(f)));
    }
    // The series record may lack what the files have (no DICOMDIR): ask the first file.
    if (vtkDICOMMetaData* md = directory->GetMetaDataForSeries(s); md != nullptr && md->GetNumberOfInstances() > 0) {
      auto fill = [&](std::string& field, vtkDICOMTag tag) {
        if (field.empty()) {
          const vtkDICOMValue& v = md->Get(0, tag);
          if (v.IsValid()) field = detail::trim(v.AsUTF8String());
        }
      };
      fill(info.series_description, DC::SeriesDescription);
      fill(info.modality, DC::Modality);
      fill(info.patient_name, DC::PatientName);
      fill(info.study_description, DC::StudyDescription);
    }
    auto copy = vtkSmartPointer<vtkStringArray>::New();
    copy->DeepCopy(names);
    readGeometry(copy, info);
    if (info.slice_count == 0) info.slice_count = info.file_count;
    if (progress) progress(s + 1, n_series);
  }
  return out;
}

}  // namespace detail

LoadedVolume loadDicomSeries(const DicomSeriesInfo& series) {
  if (series.files.empty()) {
    detail::fail(series.folder, "series " + std::to_string(series.index + 1) + " has no image files");
  }
  // loadVolume() on one file of a series reads exactly that series (sorted, rescaled, checked).
  LoadedVolume volume = loadVolume(series.files.front());
  if (volume.info.description.empty()) volume.info.description = series.series_description;
  return volume;
}

LoadedVolume loadDicomSeries(const fs::path& folder, int series_index) {
  detail::VtkErrorCapture capture;
  const vtkSmartPointer<vtkDICOMDirectory> directory = scanFolder(folder, capture);
  const int n = directory->GetNumberOfSeries();
  if (series_index < 0 || series_index >= n) {
    detail::fail(folder, "series index " + std::to_string(series_index) + " out of range: the folder has " +
                             std::to_string(n) + " series (0.." + std::to_string(n - 1) + ")");
  }
  DicomSeriesInfo info;
  info.folder = folder;
  info.index = series_index;
  vtkStringArray* names = directory->GetFileNamesForSeries(series_index);
  for (vtkIdType f = 0; f < names->GetNumberOfValues(); ++f) info.files.emplace_back(std::string(names->GetValue(f)));
  return loadDicomSeries(info);
}

}  // namespace vh::io
