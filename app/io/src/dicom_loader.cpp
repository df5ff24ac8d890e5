// DICOM series loading through vtkDICOM (vtkDICOMDirectory + vtkDICOMReader).
//
// World frame W = DICOM patient LPS, in metres. Stored pixel values are kept as stored with the
// series' RescaleSlope / RescaleIntercept as the field's value_scale / value_offset when they
// are the same for every slice; otherwise vtkDICOM rescales (AutoRescale) and the field holds
// data units directly.
#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Core>
#include <vtkDICOMDictHash.h>
#include <vtkDICOMDirectory.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMParser.h>
#include <vtkDICOMReader.h>
#include <vtkDICOMSliceSorter.h>
#include <vtkDICOMValue.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkMatrix4x4.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>

#include "loader_internal.h"
#include "vtk_error_capture.h"

namespace vh::io::detail {
namespace {

bool samePath(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  const bool eq = fs::equivalent(a, b, ec);
  return !ec && eq;
}

std::string fileName(vtkStringArray* files, int index) {
  if (index < 0 || index >= files->GetNumberOfValues()) return "?";
  return fs::path(std::string(files->GetValue(index))).filename().string();
}

/// Numeric values of an attribute of instance i ("" -> empty).
std::vector<double> values(vtkDICOMMetaData* md, int i, vtkDICOMTag tag) {
  const vtkDICOMValue& v = md->Get(i, tag);
  std::vector<double> out;
  if (!v.IsValid()) return out;
  out.resize(v.GetNumberOfValues());
  if (!out.empty()) v.GetValues(out.data(), out.size());
  return out;
}

std::string describe(const std::vector<double>& v) {
  std::ostringstream os;
  for (std::size_t i = 0; i < v.size(); ++i) os << (i ? "\\" : "") << v[i];
  return v.empty() ? std::string("(absent)") : os.str();
}

bool nearlyEqual(const std::vector<double>& a, const std::vector<double>& b, double tol) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::abs(a[i] - b[i]) > tol * std::max(1.0, std::abs(a[i]))) return false;
  }
  return true;
}

/// Every file of the series must have the same matrix size, pixel spacing, orientation and
/// pixel format; otherwise the "volume" is not one grid.
void checkConsistentSlices(vtkDICOMMetaData* md, vtkStringArray* files, const fs::path& path) {
  struct Attribute {
    vtkDICOMTag tag;
    const char* name;
    double tol;
  };
  const Attribute attributes[] = {
      {DC::Rows, "Rows", 0.0},
      {DC::Columns, "Columns", 0.0},
      {DC::PixelSpacing, "PixelSpacing", 1e-4},
      {DC::ImageOrientationPatient, "ImageOrientationPatient", 1e-4},
      {DC::BitsAllocated, "BitsAllocated", 0.0},
      {DC::PixelRepresentation, "PixelRepresentation", 0.0},
      {DC::SamplesPerPixel, "SamplesPerPixel", 0.0},
  };
  const int n = md->GetNumberOfInstances();
  for (const auto& a : attributes) {
    const auto first = values(md, 0, a.tag);
    for (int i = 1; i < n; ++i) {
      const auto v = values(md, i, a.tag);
      if (!nearlyEqual(first, v, a.tol)) {
        fail(path, std::string("inconsistent slices in the series: ") + fileName(files, i) +
                       " has " + a.name + " " + describe(v) + " where " + fileName(files, 0) +
                       " has " + describe(first));
      }
    }
  }
}

/// Whether every file has the same rescale slope and intercept; returns them through the out
/// parameters (1 and 0 when absent).
bool uniformRescale(vtkDICOMMetaData* md, double& slope, double& intercept) {
  const int n = md->GetNumberOfInstances();
  auto get = [&](int i, vtkDICOMTag tag, double fallback) {
    const vtkDICOMValue& v = md->Get(i, tag);
    return v.IsValid() && v.GetNumberOfValues() > 0 ? v.AsDouble() : fallback;
  };
  slope = get(0, DC::RescaleSlope, 1.0);
  intercept = get(0, DC::RescaleIntercept, 0.0);
  for (int i = 1; i < n; ++i) {
    if (get(i, DC::RescaleSlope, 1.0) != slope || get(i, DC::RescaleIntercept, 0.0) != intercept) {
      return false;
    }
  }
  return std::isfinite(slope) && std::isfinite(intercept) && slope != 0.0;
}

/// Slices must be evenly spaced along the slice normal (a missing slice would otherwise be
/// silently stretched over).
void checkSliceSpacing(vtkDICOMMetaData* md, vtkStringArray* files, const Eigen::Vector3d& normal,
                       double spacing_mm, int n_slices, const fs::path& path) {
  std::vector<double> d;
  std::vector<int> file_of_slice;
  for (int k = 0; k < n_slices; ++k) {
    const int file = md->GetFileIndex(k);
    const int frame = md->GetFrameIndex(k);
    if (file < 0) return;
    const vtkDICOMValue& v = md->Get(file, frame < 0 ? 0 : frame, DC::ImagePositionPatient);
    if (!v.IsValid() || v.GetNumberOfValues() != 3) return;  // no positions: nothing to check
    double p[3];
    v.GetValues(p, 3);
    d.push_back(normal.dot(Eigen::Vector3d(p[0], p[1], p[2])));
    file_of_slice.push_back(file);
  }
  for (std::size_t k = 1; k < d.size(); ++k) {
    const double gap = std::abs(d[k] - d[k - 1]);
    if (std::abs(gap - spacing_mm) > 0.1 * spacing_mm + 1e-3) {
      std::ostringstream os;
      os << "inconsistent slices in the series: uneven slice spacing, " << gap << " mm between "
         << fileName(files, file_of_slice[k - 1]) << " and " << fileName(files, file_of_slice[k])
         << " where the series spacing is " << spacing_mm << " mm (missing or duplicate slice?)";
      fail(path, os.str());
    }
  }
}

/// After the reader failed: names the first file of the series that cannot be parsed or whose
/// pixel data is cut short, with the reason; "" when every file looks whole.
std::string findCorruptFile(vtkStringArray* files) {
  for (vtkIdType i = 0; i < files->GetNumberOfValues(); ++i) {
    const std::string name = files->GetValue(i);
    VtkErrorCapture capture;
    auto meta = vtkSmartPointer<vtkDICOMMetaData>::New();
    auto parser = vtkSmartPointer<vtkDICOMParser>::New();
    capture.watch(parser);
    parser->SetMetaData(meta);
    parser->SetFileName(name.c_str());
    parser->Update();
    const std::string file = fs::path(name).filename().string();
    if (capture.hasErrors()) return file + ": " + capture.firstError();
    if (!parser->GetPixelDataFound()) return file + ": no pixel data";
    const unsigned int vl = parser->GetPixelDataVL();
    if (vl != 0xffffffffu && parser->GetFileOffset() + static_cast<vtkTypeInt64>(vl) > parser->GetFileSize()) {
      return file + ": pixel data cut short (" +
             std::to_string(parser->GetFileSize() - parser->GetFileOffset()) + " of " +
             std::to_string(vl) + " bytes)";
    }
  }
  return {};
}

/// Throws the LoadError for a reader failure: inconsistent slices when vtkDICOM says so, else
/// the corrupt file found by findCorruptFile, else VTK's message.
[[noreturn]] void failRead(const fs::path& path, vtkStringArray* files, const std::string& vtk) {
  if (vtk.find("Inconsistent") != std::string::npos || vtk.find("inconsistent") != std::string::npos) {
    fail(path, "inconsistent slices in the series: " + vtk);
  }
  const std::string corrupt = findCorruptFile(files);
  if (!corrupt.empty()) fail(path, "corrupt DICOM file " + corrupt);
  fail(path, "corrupt DICOM series: " + vtk);
}

}  // namespace

LoadedVolume loadDicom(const fs::path& path) {
  const bool is_dir = fs::is_directory(path);
  const fs::path folder = is_dir ? path : (path.has_parent_path() ? path.parent_path() : ".");
  VtkErrorCapture capture;

  auto directory = vtkSmartPointer<vtkDICOMDirectory>::New();
  capture.watch(directory);
  directory->SetDirectoryName(folder.string().c_str());
  directory->SetScanDepth(is_dir ? 2 : 1);  // a folder and its sub-folders, or the file's folder
  directory->IgnoreDicomdirOn();            // scan the files themselves; a DICOMDIR may be stale
  directory->RequirePixelDataOn();
  directory->Update();

  int chosen = -1;
  const int n_series = directory->GetNumberOfSeries();
  for (int s = 0; s < n_series; ++s) {
    vtkStringArray* names = directory->GetFileNamesForSeries(s);
    if (!is_dir) {
      for (vtkIdType f = 0; f < names->GetNumberOfValues(); ++f) {
        if (samePath(fs::path(std::string(names->GetValue(f))), path)) chosen = s;
      }
    } else if (chosen < 0 || names->GetNumberOfValues() >
                                 directory->GetFileNamesForSeries(chosen)->GetNumberOfValues()) {
      chosen = s;
    }
  }
  if (chosen < 0) {
    const std::string vtk = capture.hasErrors() ? " (" + capture.firstError() + ")" : "";
    if (is_dir) fail(path, "no DICOM image series found in the folder" + vtk);
    fail(path, "not a volume: not a readable DICOM image (corrupt, not DICOM, or no pixel data)" +
                   vtk);
  }
  vtkStringArray* files = directory->GetFileNamesForSeries(chosen);

  auto reader = vtkSmartPointer<vtkDICOMReader>::New();
  capture.watch(reader);
  capture.watch(reader->GetSorter());  // warns about gaps; reported below as uneven spacing
  reader->SetFileNames(files);
  reader->SortingOn();
  reader->SetMemoryRowOrderToFileNative();  // rows top-down as stored: D = the DICOM axes
  reader->TimeAsVectorOff();
  reader->SetDesiredTimeIndex(0);  // a 4-D series gives its first time point
  reader->AutoRescaleOff();
  reader->UpdateInformation();
  if (capture.hasErrors()) failRead(path, files, capture.firstError());
  vtkDICOMMetaData* md = reader->GetMetaData();
  if (md == nullptr || md->GetNumberOfInstances() == 0) fail(path, "no DICOM slices could be read");
  checkConsistentSlices(md, files, path);

  double slope = 1.0;
  double intercept = 0.0;
  const bool keep_stored = uniformRescale(md, slope, intercept);
  if (!keep_stored) {
    // Per-slice rescaling: let vtkDICOM convert to data units (int16 when exact, else float).
    reader->AutoRescaleOn();
    slope = 1.0;
    intercept = 0.0;
  }
  reader->Update();
  if (capture.hasErrors()) failRead(path, files, capture.firstError());
  vtkImageData* out = reader->GetOutput();
  if (out == nullptr) fail(path, "no voxel data was read");

  // Geometry: p_LPS[mm] = M * (o + S * ijk); M = patient matrix (rotation + translation).
  vtkMatrix4x4* m = reader->GetPatientMatrix();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  if (m != nullptr) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) rotation(r, c) = m->GetElement(r, c);
      translation[r] = m->GetElement(r, 3);
    }
  }
  double s[3];
  double o[3];
  out->GetSpacing(s);
  out->GetOrigin(o);
  Eigen::Matrix3d direction;
  Eigen::Vector3d axis_lengths;
  splitAxes(rotation, path, direction, axis_lengths);
  const Eigen::Vector3d spacing_mm = Eigen::Vector3d(s[0], s[1], s[2]).cwiseAbs().cwiseProduct(axis_lengths);
  int dims[3];
  out->GetDimensions(dims);
  if (dims[2] >= 2) {
    checkSliceSpacing(md, files, direction.col(2), spacing_mm[2], dims[2], path);
  }

  RawVolume raw;
  raw.image = out;
  raw.value_scale = slope;
  raw.value_offset = intercept;
  raw.geometry.spacing_m = spacing_mm * 1e-3;
  raw.geometry.direction_W = direction;
  raw.geometry.origin_W_m = (rotation * Eigen::Vector3d(o[0], o[1], o[2]) + translation) * 1e-3;
  raw.info.format = "DICOM";
  raw.info.modality = md->Get(0, DC::Modality).AsString();
  if (raw.info.modality == "CT") raw.info.value_unit = "HU";
  raw.info.description = md->Get(0, DC::SeriesDescription).AsUTF8String();
  if (raw.info.description.empty()) raw.info.description = folder.filename().string();
  raw.info.patient_name = md->Get(0, DC::PatientName).AsUTF8String();
  return finishVolume(std::move(raw), path);
}

}  // namespace vh::io::detail
