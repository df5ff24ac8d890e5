// DICOM series loading through vtkDICOM (vtkDICOMDirectory + vtkDICOMReader).
//
// World frame W = DICOM patient LPS, in metres. Stored pixel values are kept as stored with the
// series' RescaleSlope / RescaleIntercept as the field's value_scale / value_offset when they
// are the same for every slice; otherwise vtkDICOM rescales (AutoRescale) and the field holds
// data units directly. A PET series in Bq/ml becomes SUV (body weight) through the same scale
// and offset (pet_suv.h).
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <map>
#include <sstream>
#include <tuple>
#include <type_traits>

#include <Eigen/Core>
#include <vtkDICOMDictHash.h>
#include <vtkDICOMDirectory.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMParser.h>
#include <vtkDICOMReader.h>
#include <vtkDICOMSliceSorter.h>
#include <vtkDICOMValue.h>
#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkDICOMItem.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkIntArray.h>
#include <vtkMatrix4x4.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>

#include "loader_internal.h"
#include "pet_suv.h"
#include "slice_stack.h"
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


std::string fixed(double v, int digits) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(digits) << v;
  return os.str();
}

std::string seriesText(const vtkDICOMItem& record, vtkDICOMMetaData* md, vtkDICOMTag tag) {
  const vtkDICOMValue& v = record.Get(tag);
  if (v.IsValid() && !trim(v.AsUTF8String()).empty()) return trim(v.AsUTF8String());
  if (md != nullptr && md->GetNumberOfInstances() > 0) {
    const vtkDICOMValue& f = md->Get(0, tag);
    if (f.IsValid()) return trim(f.AsUTF8String());
  }
  return {};
}

/// "series 3 'BONE 1MM' (140 files)"
std::string seriesName(vtkDICOMDirectory* directory, int s) {
  vtkDICOMMetaData* md = directory->GetMetaDataForSeries(s);
  const vtkDICOMItem& record = directory->GetSeriesRecord(s);
  const std::string number = seriesText(record, md, DC::SeriesNumber);
  const std::string description = seriesText(record, md, DC::SeriesDescription);
  std::string out = "series " + (number.empty() ? "#" + std::to_string(s + 1) : number);
  if (!description.empty()) out += " '" + description + "'";
  return out + " (" + std::to_string(directory->GetFileNamesForSeries(s)->GetNumberOfValues()) + " files)";
}

/// Series indices of `directory` that `selector` names: a series number, a Series Instance UID
/// or text in the series description (case-insensitive); in that order of precedence.
std::vector<int> seriesMatching(vtkDICOMDirectory* directory, const std::string& selector) {
  const int n = directory->GetNumberOfSeries();
  const auto number = parseInt(selector);
  std::vector<int> by_number, by_uid, by_description;
  const std::string wanted = toLower(selector);
  for (int s = 0; s < n; ++s) {
    vtkDICOMMetaData* md = directory->GetMetaDataForSeries(s);
    const vtkDICOMItem& record = directory->GetSeriesRecord(s);
    const auto series_number = parseInt(seriesText(record, md, DC::SeriesNumber));
    if (number && series_number && *number == *series_number) by_number.push_back(s);
    if (seriesText(record, md, DC::SeriesInstanceUID) == selector) by_uid.push_back(s);
    if (toLower(seriesText(record, md, DC::SeriesDescription)).find(wanted) != std::string::npos) {
      by_description.push_back(s);
    }
  }
  if (!by_number.empty()) return by_number;
  if (!by_uid.empty()) return by_uid;
  return by_description;
}

/// Whether `path` is a DICOMDIR (Media Storage Directory), by name or by its header.
bool isDicomdir(const fs::path& path) {
  if (toLower(path.filename().string()) == "dicomdir") return true;
  VtkErrorCapture capture;
  auto meta = vtkSmartPointer<vtkDICOMMetaData>::New();
  auto parser = vtkSmartPointer<vtkDICOMParser>::New();
  capture.watch(parser);
  parser->SetMetaData(meta);
  parser->SetFileName(path.string().c_str());
  parser->SetQueryItem(vtkDICOMItem());
  parser->Update();
  if (capture.hasErrors() || meta->GetNumberOfInstances() == 0) return false;
  return meta->Get(DC::MediaStorageSOPClassUID).AsString() == "1.2.840.10008.1.3.10";
}

/// A DICOM load's progress from the reader's ProgressEvent, and cancelling through
/// AbortExecute.
struct ReaderProgress {
  const VolumeLoadOptions* options = nullptr;
  double begin = 0.0, end = 1.0;  // the part of the whole load this read stands for
  static void callback(vtkObject* caller, unsigned long, void* client, void* call) {
    auto* self = static_cast<ReaderProgress*>(client);
    const double fraction = call != nullptr ? *static_cast<double*>(call) : 0.0;
    if (self->options->progress) self->options->progress(self->begin + fraction * (self->end - self->begin));
    if (self->options->cancel != nullptr && self->options->cancel->load(std::memory_order_relaxed)) {
      static_cast<vtkAlgorithm*>(caller)->SetAbortExecute(1);
    }
  }
};

bool cancelled(const VolumeLoadOptions& options) {
  return options.cancel != nullptr && options.cancel->load(std::memory_order_relaxed);
}

[[noreturn]] void failCancelled(const fs::path& path) {
  throw LoadCancelled(path.string() + ": loading cancelled");
}

vtkSmartPointer<vtkDICOMReader> makeReader(vtkStringArray* files, VtkErrorCapture& capture) {
  auto reader = vtkSmartPointer<vtkDICOMReader>::New();
  capture.watch(reader);
  capture.watch(reader->GetSorter());  // warns about gaps; measured and corrected below
  reader->SetFileNames(files);
  reader->SortingOn();
  reader->SetMemoryRowOrderToFileNative();  // rows top-down as stored: D = the DICOM axes
  reader->TimeAsVectorOff();
  reader->AutoRescaleOff();
  return reader;
}

/// SOP Class UID of a DICOM Segmentation Storage object (DICOM PS3.4 B.5).
constexpr const char* kSegmentationSopClass = "1.2.840.10008.5.1.4.1.1.66.4";

/// Files of a single-frame series at the same position and time point / echo as an earlier
/// file (exact duplicates, e.g. a slice exported twice): their indices, with a description.
std::vector<int> duplicateFiles(vtkDICOMMetaData* md, vtkStringArray* files, std::string& description) {
  const int n = md->GetNumberOfInstances();
  std::map<std::tuple<long long, long long, long long, std::string>, int> seen;
  std::vector<int> out;
  std::ostringstream os;
  for (int i = 0; i < n; ++i) {
    if (md->Get(i, DC::NumberOfFrames).AsInt() > 1) return {};  // multi-frame: the reader's affair
    const auto p = values(md, i, DC::ImagePositionPatient);
    if (p.size() != 3) return {};
    // Positions to a micrometre; the acquisition keys that tell time points and echoes apart.
    const std::string key = md->Get(i, DC::TemporalPositionIdentifier).AsString() + "|" +
                            md->Get(i, DC::EchoNumbers).AsString() + "|" + md->Get(i, DC::TriggerTime).AsString() +
                            "|" + md->Get(i, DC::EchoTime).AsString() + "|" +
                            md->Get(i, DC::DiffusionBValue).AsString();
    const auto pos = std::make_tuple(std::llround(p[0] * 1e3), std::llround(p[1] * 1e3), std::llround(p[2] * 1e3), key);
    const auto [it, inserted] = seen.emplace(pos, i);
    if (!inserted) {
      if (!out.empty()) os << ", ";
      os << fileName(files, i) << " (same as " << fileName(files, it->second) << ")";
      out.push_back(i);
    }
  }
  description = os.str();
  return out;
}

/// The voxels of `image` resampled onto `grid` (same scalar type), or null when cancelled.
vtkSmartPointer<vtkImageData> resampled(vtkImageData* image, const SliceStack& stack, const RegularGrid& grid,
                                        const VolumeLoadOptions& options, double progress_begin) {
  auto out = vtkSmartPointer<vtkImageData>::New();
  out->SetDimensions(grid.dims[0], grid.dims[1], grid.dims[2]);
  out->AllocateScalars(image->GetScalarType(), 1);
  const double background = image->GetScalarRange()[0];  // air, or the scanner's padding
  const auto progress = [&](double f) {
    if (options.progress) options.progress(progress_begin + f * (1.0 - progress_begin));
  };
  const auto run = [&](auto* in) {
    using T = std::remove_const_t<std::remove_pointer_t<decltype(in)>>;
    return resampleStack<T>(in, stack, grid, static_cast<T>(background), static_cast<T*>(out->GetScalarPointer()),
                            progress, options.cancel);
  };
  void* in = image->GetScalarPointer();
  bool done = false;
  switch (image->GetScalarType()) {
    case VTK_UNSIGNED_CHAR: done = run(static_cast<const std::uint8_t*>(in)); break;
    case VTK_SIGNED_CHAR:
    case VTK_CHAR: done = run(static_cast<const std::int8_t*>(in)); break;
    case VTK_SHORT: done = run(static_cast<const std::int16_t*>(in)); break;
    case VTK_UNSIGNED_SHORT: done = run(static_cast<const std::uint16_t*>(in)); break;
    case VTK_INT: done = run(static_cast<const std::int32_t*>(in)); break;
    case VTK_UNSIGNED_INT: done = run(static_cast<const std::uint32_t*>(in)); break;
    case VTK_FLOAT: done = run(static_cast<const float*>(in)); break;
    case VTK_DOUBLE: done = run(static_cast<const double*>(in)); break;
    default:
      throw LoadError(std::string("cannot resample voxels of type ") + image->GetScalarTypeAsString());
  }
  return done ? out : nullptr;
}

/// A series' reader, with the file list it reads.
struct OpenedSeries {
  vtkSmartPointer<vtkStringArray> files;
  vtkSmartPointer<vtkDICOMReader> reader;
  vtkDICOMMetaData* md = nullptr;  ///< The reader's (after UpdateInformation); may be null.
};

/// Opens `series_files` with exact duplicate files dropped (a notice in `info` names them): the
/// slice sorter would take them for a second time point.
OpenedSeries openWithoutDuplicates(vtkStringArray* series_files, VtkErrorCapture& capture, VolumeInfo& info) {
  OpenedSeries s;
  s.files = vtkSmartPointer<vtkStringArray>::New();
  s.files->DeepCopy(series_files);
  s.reader = makeReader(s.files, capture);
  s.reader->UpdateInformation();
  s.md = s.reader->GetMetaData();
  if (s.md == nullptr || s.md->GetNumberOfInstances() <= 1) return s;
  std::string which;
  const std::vector<int> duplicates = duplicateFiles(s.md, s.files, which);
  if (duplicates.empty()) return s;
  auto kept = vtkSmartPointer<vtkStringArray>::New();
  for (vtkIdType f = 0; f < s.files->GetNumberOfValues(); ++f) {
    if (std::find(duplicates.begin(), duplicates.end(), static_cast<int>(f)) == duplicates.end()) {
      kept->InsertNextValue(s.files->GetValue(f));
    }
  }
  info.notices.push_back("dropped " + std::to_string(duplicates.size()) + " duplicate slice" +
                         (duplicates.size() > 1 ? "s" : "") + ": " + which);
  s.files = kept;
  capture.clear();
  s.reader = makeReader(s.files, capture);
  s.reader->UpdateInformation();
  s.md = s.reader->GetMetaData();
  return s;
}

/// 4-D series (cardiac phases, dynamic frames, echoes): sets the reader to time point
/// options.dicom_phase, recorded in `info` (with a notice for a 4-D series).
/// @throws LoadError naming `path` when the series has no such time point.
void chooseTimePoint(vtkDICOMReader* reader, const VolumeLoadOptions& options, const fs::path& path,
                     VolumeInfo& info) {
  const int time_points = std::max(1, reader->GetTimeDimension());
  info.phase_count = time_points;
  if (options.dicom_phase < 0 || options.dicom_phase >= time_points) {
    fail(path, "time point " + std::to_string(options.dicom_phase + 1) + " asked for, but the series has " +
                   std::to_string(time_points) + (time_points == 1 ? " (it is not 4-D)" : ""));
  }
  info.phase = options.dicom_phase;
  reader->SetDesiredTimeIndex(options.dicom_phase);
  if (time_points > 1) {
    info.notices.push_back("4-D series with " + std::to_string(time_points) +
                           " time points (phases or echoes): loaded time point " +
                           std::to_string(options.dicom_phase + 1) + " (choose another with the phase option)");
  }
}

/// Reads the voxels (progress 0 to 0.7 of the load). The stored values are kept when every
/// slice has the same rescaling (`slope`, `intercept` set to it), else vtkDICOM converts to data
/// units (int16 when exact, else float) and they are 1 and 0.
/// @return the reader's output (owned by `reader`).
/// @throws LoadError naming `path` for a read error or no voxels; LoadCancelled.
vtkImageData* readVoxels(const OpenedSeries& series, VtkErrorCapture& capture, const VolumeLoadOptions& options,
                         const fs::path& path, double& slope, double& intercept) {
  slope = 1.0;
  intercept = 0.0;
  if (!uniformRescale(series.md, slope, intercept)) {
    series.reader->AutoRescaleOn();
    slope = 1.0;
    intercept = 0.0;
  }
  ReaderProgress progress{&options, 0.0, 0.7};
  auto observer = vtkSmartPointer<vtkCallbackCommand>::New();
  observer->SetCallback(&ReaderProgress::callback);
  observer->SetClientData(&progress);
  const unsigned long tag = series.reader->AddObserver(vtkCommand::ProgressEvent, observer);
  series.reader->Update();
  series.reader->RemoveObserver(tag);  // `progress` ends here
  if (cancelled(options)) failCancelled(path);
  if (capture.hasErrors()) failRead(path, series.files, capture.firstError());
  vtkImageData* out = series.reader->GetOutput();
  if (out == nullptr) fail(path, "no voxel data was read");
  return out;
}

/// The reader's patient matrix M: p_LPS[mm] = M * (o + S * ijk) (rotation and translation);
/// identity when it has none.
void patientMatrixOf(vtkDICOMReader* reader, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation_mm) {
  rotation.setIdentity();
  translation_mm.setZero();
  vtkMatrix4x4* m = reader->GetPatientMatrix();
  if (m == nullptr) return;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rotation(r, c) = m->GetElement(r, c);
    translation_mm[r] = m->GetElement(r, 3);
  }
}

/// The image plane of the first slice: its row and column directions (unit, patient LPS) and
/// its pixel spacing [mm] into `stack`, from ImageOrientationPatient and PixelSpacing (per frame
/// or in the shared functional groups for multi-frame files). False, nothing changed, when
/// absent.
bool readImagePlane(vtkDICOMMetaData* md, Eigen::Vector3d& row_dir, Eigen::Vector3d& col_dir, SliceStack& stack) {
  const auto iop = values(md, 0, DC::ImageOrientationPatient);
  const auto spacing = values(md, 0, DC::PixelSpacing);
  if (iop.size() == 6 && spacing.size() == 2) {
    row_dir = Eigen::Vector3d(iop[0], iop[1], iop[2]).normalized();
    col_dir = Eigen::Vector3d(iop[3], iop[4], iop[5]).normalized();
    stack.row_spacing_mm = spacing[0];
    stack.column_spacing_mm = spacing[1];
    return true;
  }
  const int file = std::max(0, md->GetFileIndex(0));
  const int frame = std::max(0, md->GetFrameIndex(0));
  const vtkDICOMValue& o6 = md->Get(file, frame, DC::ImageOrientationPatient);
  const vtkDICOMValue& ps = md->Get(file, frame, DC::PixelSpacing);
  if (!(o6.IsValid() && o6.GetNumberOfValues() == 6 && ps.IsValid() && ps.GetNumberOfValues() == 2)) return false;
  double q[6], sp[2];
  o6.GetValues(q, 6);
  ps.GetValues(sp, 2);
  row_dir = Eigen::Vector3d(q[0], q[1], q[2]).normalized();
  col_dir = Eigen::Vector3d(q[3], q[4], q[5]).normalized();
  stack.row_spacing_mm = sp[0];
  stack.column_spacing_mm = sp[1];
  return true;
}

/// Each slice's ImagePositionPatient [mm, patient LPS], slices 0 .. `slices` - 1 in the
/// reader's order; false when one is missing.
bool readSlicePositions(vtkDICOMMetaData* md, int slices, std::vector<Eigen::Vector3d>& positions_mm) {
  for (int k = 0; k < slices; ++k) {
    const int file = md->GetFileIndex(k);
    const int frame = std::max(0, md->GetFrameIndex(k));
    if (file < 0) return false;
    const vtkDICOMValue& v = md->Get(file, frame, DC::ImagePositionPatient);
    if (!v.IsValid() || v.GetNumberOfValues() != 3) return false;
    double p[3];
    v.GetValues(p, 3);
    positions_mm.emplace_back(p[0], p[1], p[2]);
  }
  return true;
}

/// Each slice's SliceThickness [mm], slices 0 .. `slices` - 1 in the reader's order (per file,
/// or per frame of a multi-frame file); empty when a slice has none or a non-positive one.
std::vector<double> readSliceThickness(vtkDICOMMetaData* md, int slices) {
  std::vector<double> thickness_mm;
  for (int k = 0; k < slices; ++k) {
    const int file = md->GetFileIndex(k);
    const int frame = std::max(0, md->GetFrameIndex(k));
    if (file < 0) return {};
    const vtkDICOMValue& v = md->Get(file, frame, DC::SliceThickness);
    const double t = v.IsValid() && v.GetNumberOfValues() > 0 ? v.AsDouble() : 0.0;
    if (!(t > 0.0) || !std::isfinite(t)) return {};
    thickness_mm.push_back(t);
  }
  return thickness_mm;
}

/// The slices as acquired, in the plane frame (u, v, d) of the first slice: u = row_dir,
/// v = col_dir, d = normal (unit, patient LPS, d growing with k), first = slice 0's first pixel
/// [mm, LPS]. `analysis` is left default (regular, no median) when the positions or the plane
/// are missing or the plane axes are not orthogonal.
struct SliceGeometry {
  SliceStack stack;
  Eigen::Vector3d row_dir, col_dir, normal;
  Eigen::Vector3d first_mm = Eigen::Vector3d::Zero();
  StackAnalysis analysis;
};

/// The slice geometry of a read with `dims` voxels; the plane axes default to the patient
/// matrix's `rotation` columns.
/// @throws LoadError naming `path` when two slices lie at the same position.
SliceGeometry sliceGeometry(vtkDICOMMetaData* md, vtkStringArray* files, const Eigen::Matrix3d& rotation,
                            const int dims[3], const fs::path& path) {
  SliceGeometry g;
  g.row_dir = rotation.col(0).normalized();
  g.col_dir = rotation.col(1).normalized();
  bool have_positions = dims[2] >= 2;
  if (!readImagePlane(md, g.row_dir, g.col_dir, g.stack)) have_positions = false;
  g.normal = g.row_dir.cross(g.col_dir);
  std::vector<Eigen::Vector3d> positions;
  if (have_positions) have_positions = readSlicePositions(md, dims[2], positions);
  if (!have_positions || !(std::abs(g.row_dir.dot(g.col_dir)) < 1e-3) || !(g.stack.row_spacing_mm > 0.0) ||
      !(g.stack.column_spacing_mm > 0.0)) {
    return g;
  }
  g.first_mm = positions.front();
  if (g.normal.dot(positions.back() - g.first_mm) < 0.0) g.normal = -g.normal;  // d grows with k
  g.normal.normalize();
  g.stack.columns = dims[0];
  g.stack.rows = dims[1];
  for (const auto& p : positions) {
    const Eigen::Vector3d q = p - g.first_mm;
    g.stack.offset_mm.emplace_back(q.dot(g.row_dir), q.dot(g.col_dir), q.dot(g.normal));
  }
  for (std::size_t k = 1; k < g.stack.offset_mm.size(); ++k) {
    if (!(g.stack.offset_mm[k].z() > g.stack.offset_mm[k - 1].z())) {
      fail(path, "inconsistent slices in the series: two slices at the same position (" +
                     fileName(files, md->GetFileIndex(static_cast<int>(k - 1))) + " and " +
                     fileName(files, md->GetFileIndex(static_cast<int>(k))) + ") with different pixels or times");
    }
  }
  g.stack.thickness_mm = readSliceThickness(md, dims[2]);
  g.analysis = analyseStack(g.stack);
  return g;
}

/// "slices in 2 parts: 14 at 4.00 mm (4.00 mm thick), then 13 at 7.00 mm (7.00 mm thick)"
std::string partsText(const std::vector<SlicePart>& parts) {
  std::string out = "slices in " + std::to_string(parts.size()) + " parts: ";
  for (std::size_t p = 0; p < parts.size(); ++p) {
    out += (p > 0 ? ", then " : "") + std::to_string(parts[p].slices()) + " at " + fixed(parts[p].spacing_mm, 2) +
           " mm";
    if (parts[p].thickness_mm > 0.0) out += " (" + fixed(parts[p].thickness_mm, 2) + " mm thick)";
  }
  return out;
}

/// The notices of a regularised stack: shear (gantry tilt), parts of different spacing, missing
/// slices, uneven spacing (only where the parts and gaps do not explain it).
void regularisationNotices(const SliceGeometry& g, const RegularGrid& grid, vtkDICOMMetaData* md,
                           vtkStringArray* files, const std::string& modality, VolumeInfo& info) {
  const StackAnalysis& analysis = g.analysis;
  if (analysis.sheared) {
    const vtkDICOMValue& tilt = md->Get(0, DC::GantryDetectorTilt);
    const bool is_tilt = modality == "CT" || (tilt.IsValid() && tilt.AsDouble() != 0.0);
    std::string text = std::string(is_tilt ? "resampled from a gantry tilt of " : "resampled from a sheared slice stack of ") +
                       fixed(analysis.shear_deg, 1) + " deg";
    if (grid.dims[0] != g.stack.columns || grid.dims[1] != g.stack.rows)  // the footprints' union, so no anatomy is cut
      text += " onto " + std::to_string(grid.dims[0]) + " x " + std::to_string(grid.dims[1]) + " pixels a slice (the slices are " +
              std::to_string(g.stack.columns) + " x " + std::to_string(g.stack.rows) + ")";
    info.notices.push_back(text);
  }
  if (!analysis.parts.empty()) {
    info.notices.push_back(partsText(analysis.parts) + ": resampled to " + fixed(grid.spacing_mm.z(), 2) + " mm");
  }
  const double d0_mm = g.first_mm.dot(g.normal);
  for (const SliceGap& gap : analysis.gaps) {
    const int before = md->GetFileIndex(gap.slice), after = md->GetFileIndex(gap.slice + 1);
    info.notices.push_back(
        "missing slice" + std::string(gap.missing > 1 ? "s" : "") + ": a gap of " +
        fixed(gap.d_after_mm - gap.d_before_mm, 2) + " mm (about " + std::to_string(gap.missing) +
        " slice" + (gap.missing > 1 ? "s" : "") + ") between " + fileName(files, before) + " at " +
        fixed(d0_mm + gap.d_before_mm, 2) + " mm and " + fileName(files, after) + " at " +
        fixed(d0_mm + gap.d_after_mm, 2) + " mm along the slice normal, filled by linear interpolation");
  }
  if (analysis.uneven && (analysis.parts.empty() || analysis.irregular_steps)) {
    info.notices.push_back("uneven slice spacing (" + fixed(analysis.min_spacing_mm, 3) + " to " +
                           fixed(analysis.max_spacing_mm, 3) + " mm): resampled to " +
                           fixed(grid.spacing_mm.z(), 3) + " mm (" +
                           (analysis.parts.empty() ? "the median spacing" : "the finest part's spacing") + ")");
  }
}

/// Regularises an irregular stack: resamples `out` onto the grid of the image planes (u, v, d)
/// with the median spacing, or the finest part's for a stack in parts (progress 0.7 to 1), into
/// raw.image and raw.geometry (W = patient LPS [m]), with notices.
/// @throws LoadError naming `path` when no grid fits; LoadCancelled.
void regularise(vtkImageData* out, const SliceGeometry& g, vtkDICOMMetaData* md, vtkStringArray* files,
                const std::string& modality, const VolumeLoadOptions& options, const fs::path& path, RawVolume& raw) {
  RegularGrid grid;
  try {
    grid = regularGridFor(g.stack, g.analysis);
  } catch (const std::invalid_argument& e) {
    fail(path, std::string("cannot regularise the slice stack: ") + e.what());
  }
  regularisationNotices(g, grid, md, files, modality, raw.info);
  vtkSmartPointer<vtkImageData> regular = resampled(out, g.stack, grid, options, 0.7);
  if (regular == nullptr) failCancelled(path);
  raw.image = regular;
  raw.geometry.direction_W.col(0) = g.row_dir;
  raw.geometry.direction_W.col(1) = g.col_dir;
  raw.geometry.direction_W.col(2) = g.normal;
  raw.geometry.spacing_m = grid.spacing_mm * 1e-3;
  raw.geometry.origin_W_m = (g.first_mm + grid.origin_mm.x() * g.row_dir + grid.origin_mm.y() * g.col_dir +
                             grid.origin_mm.z() * g.normal) * 1e-3;
}

/// The series' description fields into `info` (the folder's name when it has no description).
void describeSeries(vtkDICOMMetaData* md, const std::string& modality, const fs::path& folder, VolumeInfo& info) {
  info.format = "DICOM";
  info.modality = modality;
  if (info.modality == "CT") info.value_unit = "HU";
  info.description = md->Get(0, DC::SeriesDescription).AsUTF8String();
  if (info.description.empty()) info.description = folder.filename().string();
  info.patient_name = md->Get(0, DC::PatientName).AsUTF8String();
  info.series_uid = md->Get(0, DC::SeriesInstanceUID).AsString();
  info.frame_of_reference_uid = md->Get(0, DC::FrameOfReferenceUID).AsString();
  info.series_number = md->Get(0, DC::SeriesNumber).AsInt();
}

/// A PET series in SUV (body weight) when its header allows (pet_suv.h): the factor times the
/// value scale and offset, so the field, the rendering image, the isovalue range and the
/// histogram are all in SUV; the unit ("SUVbw", else "Bq/ml" or none) and a notice either way.
void applyPetSuv(vtkDICOMMetaData* md, RawVolume& raw) {
  const PetSuv suv = petSuv(md);
  if (suv.in_suv) {
    raw.value_scale *= suv.factor;
    raw.value_offset *= suv.factor;
  }
  raw.info.value_unit = suv.unit;
  if (!suv.notice.empty()) raw.info.notices.push_back(suv.notice);
}

/// Reads the chosen files as one volume, regularised when needed; notices appended to `raw`.
RawVolume readSeries(vtkStringArray* series_files, const fs::path& path, const fs::path& folder,
                     const VolumeLoadOptions& options) {
  VtkErrorCapture capture;
  RawVolume raw;
  const OpenedSeries series = openWithoutDuplicates(series_files, capture, raw.info);
  vtkDICOMMetaData* md = series.md;
  if (capture.hasErrors()) failRead(path, series.files, capture.firstError());
  if (md == nullptr || md->GetNumberOfInstances() == 0) fail(path, "no DICOM slices could be read");
  // A segmentation's frames are the segments, several at each slice position: read as a scan it
  // would be refused for "two slices at the same position", naming one file twice.
  if (md->Get(0, DC::Modality).AsString() == "SEG" || md->Get(0, DC::SOPClassUID).AsString() == kSegmentationSopClass) {
    fail(path, "a DICOM Segmentation (SEG), not a scan: open the scan it segments first, then this file with "
               "File > Open Segmentation (Ctrl+G); on the command line, run --segmentation FILE with the scan's scene");
  }
  checkConsistentSlices(md, series.files, path);
  chooseTimePoint(series.reader, options, path, raw.info);
  double slope = 1.0;
  double intercept = 0.0;
  vtkImageData* out = readVoxels(series, capture, options, path, slope, intercept);

  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation_mm;
  patientMatrixOf(series.reader, rotation, translation_mm);
  double s[3];
  double o[3];
  out->GetSpacing(s);
  out->GetOrigin(o);
  int dims[3];
  out->GetDimensions(dims);
  const SliceGeometry slices = sliceGeometry(md, series.files, rotation, dims, path);

  const std::string modality = md->Get(0, DC::Modality).AsString();
  if (!slices.analysis.regular() && slices.analysis.median_spacing_mm > 0.0) {
    regularise(out, slices, md, series.files, modality, options, path, raw);
  } else {
    Eigen::Matrix3d direction;
    Eigen::Vector3d axis_lengths;
    splitAxes(rotation, path, direction, axis_lengths);
    raw.image = out;
    raw.geometry.spacing_m = Eigen::Vector3d(s[0], s[1], s[2]).cwiseAbs().cwiseProduct(axis_lengths) * 1e-3;
    raw.geometry.direction_W = direction;
    raw.geometry.origin_W_m = (rotation * Eigen::Vector3d(o[0], o[1], o[2]) + translation_mm) * 1e-3;
  }
  raw.value_scale = slope;
  raw.value_offset = intercept;
  describeSeries(md, modality, folder, raw.info);
  if (modality == "PT") applyPetSuv(md, raw);
  return raw;
}

}  // namespace

RawVolume loadDicomRaw(const fs::path& path, const VolumeLoadOptions& options) {
  // A DICOMDIR opens the folder it indexes (scanned file by file: an index may be stale).
  const bool is_dir = fs::is_directory(path) || isDicomdir(path);
  const fs::path folder = fs::is_directory(path) ? path : (path.has_parent_path() ? path.parent_path() : ".");
  VtkErrorCapture capture;

  auto directory = vtkSmartPointer<vtkDICOMDirectory>::New();
  capture.watch(directory);
  directory->SetDirectoryName(folder.string().c_str());
  directory->SetScanDepth(is_dir ? kDicomScanDepth : 1);  // a folder and its sub-folders, or the file's folder
  directory->IgnoreDicomdirOn();
  directory->RequirePixelDataOn();
  directory->Update();
  if (cancelled(options)) failCancelled(path);

  const int n_series = directory->GetNumberOfSeries();
  std::vector<int> candidates;
  if (!is_dir) {
    for (int s = 0; s < n_series && candidates.empty(); ++s) {
      vtkStringArray* names = directory->GetFileNamesForSeries(s);
      for (vtkIdType f = 0; f < names->GetNumberOfValues(); ++f) {
        if (samePath(fs::path(std::string(names->GetValue(f))), path)) {
          candidates.push_back(s);
          break;
        }
      }
    }
  } else if (!options.dicom_series.empty()) {
    candidates = seriesMatching(directory, options.dicom_series);
    if (candidates.empty() && n_series > 0) {
      std::string list;
      for (int s = 0; s < n_series; ++s) list += (s ? "; " : "") + seriesName(directory, s);
      fail(path, "no series matches '" + options.dicom_series + "' (number, UID or description); the folder has: " + list);
    }
  } else {
    for (int s = 0; s < n_series; ++s) candidates.push_back(s);
  }
  // The largest first (a scout or a dose report is small).
  std::stable_sort(candidates.begin(), candidates.end(), [&](int a, int b) {
    return directory->GetFileNamesForSeries(a)->GetNumberOfValues() >
           directory->GetFileNamesForSeries(b)->GetNumberOfValues();
  });
  if (candidates.empty()) {
    const std::string vtk = capture.hasErrors() ? " (" + capture.firstError() + ")" : "";
    if (is_dir) fail(path, "no DICOM image series found in the folder" + vtk);
    fail(path, "not a volume: not a readable DICOM image (corrupt, not DICOM, or no pixel data)" + vtk);
  }
  // The first that loads: a damaged or unusable largest series falls back to the next one.
  std::vector<std::string> skipped;
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    const int chosen = candidates[c];
    try {
      RawVolume raw = readSeries(directory->GetFileNamesForSeries(chosen), path, folder, options);
      if (n_series > 1 || !skipped.empty()) {
        std::string note = "loaded " + seriesName(directory, chosen) + " of " + std::to_string(n_series) +
                           " series in the folder";
        if (is_dir && options.dicom_series.empty()) note += " (the largest usable; choose another with the series option)";
        raw.info.notices.insert(raw.info.notices.begin(), note);
      }
      for (const auto& why : skipped) raw.info.notices.push_back(why);
      return raw;
    } catch (const LoadCancelled&) {
      throw;
    } catch (const LoadError& e) {
      if (c + 1 == candidates.size() || !options.dicom_series.empty() || !is_dir) throw;
      skipped.push_back("skipped " + seriesName(directory, chosen) + ": " + e.what());
    }
  }
  fail(path, "no DICOM series could be loaded");
}

}  // namespace vh::io::detail
