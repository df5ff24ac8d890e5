// Writers of synthetic-but-real DICOM series (see dicom_fixtures.h).
//
// One vtkDICOMWriter call per series: the kept slices (times time points, times echoes, plus
// duplicates) are stacked into one staging image, one z-slice per file (or per frame), and a
// vtkDICOMCTGenerator / vtkDICOMMRGenerator subclass fills in the standard modules, then
// patches what the stock generators cannot express: the per-file ImagePositionPatient of a
// sheared, gapped, jittered or repeated stack, the temporal and echo tags, and, for the
// enhanced multi-frame file (which vtk-dicom 0.8 refuses to generate), the Enhanced CT / MR SOP
// class with shared and per-frame functional groups.

#include "dicom_fixtures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>
#include <vtkDICOMCTGenerator.h>
#include <vtkDICOMDictHash.h>
#include <vtkDICOMItem.h>
#include <vtkDICOMMRGenerator.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMReader.h>
#include <vtkDICOMSequence.h>
#include <vtkDICOMValue.h>
#include <vtkDICOMWriter.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkMatrix4x4.h>
#include <vtkObjectFactory.h>
#include <vtkStringArray.h>

namespace vh::io::test {

namespace fs = std::filesystem;

namespace {

/// Patches the generated metadata: (metadata, slice index array: instance [, frame] -> staging
/// slice) -> success.
using Patch = std::function<bool(vtkDICOMMetaData*, vtkIntArray*)>;

class FixtureCTGenerator : public vtkDICOMCTGenerator {
 public:
  static FixtureCTGenerator* New();
  vtkTypeMacro(FixtureCTGenerator, vtkDICOMCTGenerator)
  Patch patch;
  // GenerateCTInstance() directly: the stock GenerateInstance() refuses multi-frame output.
  bool GenerateInstance(vtkInformation* info) override {
    return GenerateCTInstance(info) && patch(MetaData, SliceIndexArray);
  }
};
vtkStandardNewMacro(FixtureCTGenerator);

class FixtureMRGenerator : public vtkDICOMMRGenerator {
 public:
  static FixtureMRGenerator* New();
  vtkTypeMacro(FixtureMRGenerator, vtkDICOMMRGenerator)
  Patch patch;
  bool GenerateInstance(vtkInformation* info) override {
    return GenerateMRInstance(info) && patch(MetaData, SliceIndexArray);
  }
};
vtkStandardNewMacro(FixtureMRGenerator);

/// One written file (or frame).
struct Slot {
  int k = 0;  ///< Source slice.
  int t = 0;  ///< Temporal position.
  int e = 0;  ///< Echo.
};

vtkDICOMValue ds(const Eigen::Vector3d& v) { return vtkDICOMValue(vtkDICOMVR::DS, v.data(), 3); }

vtkDICOMValue orientation(const Eigen::Vector3d& row, const Eigen::Vector3d& col) {
  const double o[6] = {row.x(), row.y(), row.z(), col.x(), col.y(), col.z()};
  return vtkDICOMValue(vtkDICOMVR::DS, o, 6);
}

vtkDICOMValue sequenceOf(const vtkDICOMItem& item) {
  vtkDICOMSequence seq;
  seq.AddItem(item);
  return vtkDICOMValue(seq);
}

/// PET Image Storage (DICOM PS3.4 B.5).
constexpr const char* kPetImageStorage = "1.2.840.10008.5.1.4.1.1.128";

bool contains(const std::vector<int>& v, int x) { return std::find(v.begin(), v.end(), x) != v.end(); }

}  // namespace

Eigen::Vector3d WrittenSeries::voxelLps(double i, double j, double k) const {
  const Eigen::Vector3d p = (source_ijk_to_lps_mm * Eigen::Vector4d(i, j, k, 1.0)).head<3>();
  const int ki = static_cast<int>(std::lround(k));
  const double jitter =
      ki >= 0 && ki < static_cast<int>(slice_jitter_mm.size()) ? slice_jitter_mm[ki] : 0.0;
  return p + jitter * normal_lps;
}

SourceVolume readSourceSeries(const fs::path& folder) {
  auto names = vtkSmartPointer<vtkStringArray>::New();
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (entry.is_regular_file()) files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) names->InsertNextValue(f);
  if (files.empty()) throw std::runtime_error(folder.string() + ": no files");

  auto reader = vtkSmartPointer<vtkDICOMReader>::New();
  reader->SetFileNames(names);
  reader->SetMemoryRowOrderToFileNative();  // memory row j = file row j
  reader->AutoRescaleOff();                 // stored values
  reader->Update();
  if (reader->GetErrorCode() != 0 || !reader->GetOutput() ||
      reader->GetOutput()->GetNumberOfPoints() == 0) {
    throw std::runtime_error(folder.string() + ": vtkDICOMReader failed");
  }
  SourceVolume src;
  src.image = vtkSmartPointer<vtkImageData>::New();
  src.image->DeepCopy(reader->GetOutput());
  double spacing[3], origin[3];
  src.image->GetSpacing(spacing);
  src.image->GetOrigin(origin);
  Eigen::Matrix4d data_from_ijk = Eigen::Matrix4d::Identity();
  for (int a = 0; a < 3; ++a) {
    data_from_ijk(a, a) = spacing[a];
    data_from_ijk(a, 3) = origin[a];
  }
  Eigen::Matrix4d lps_from_data = Eigen::Matrix4d::Identity();
  if (vtkMatrix4x4* m = reader->GetPatientMatrix()) {
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) lps_from_data(r, c) = m->GetElement(r, c);
  }
  src.ijk_to_lps_mm = lps_from_data * data_from_ijk;
  src.rescale_slope = reader->GetRescaleSlope();
  src.rescale_intercept = reader->GetRescaleIntercept();

  // Patient, study and equipment: copied from the first file into every written one.
  vtkDICOMMetaData* md = reader->GetMetaData();
  src.shared_tags = vtkSmartPointer<vtkDICOMMetaData>::New();
  for (vtkDICOMTag tag :
       {vtkDICOMTag(DC::PatientName), vtkDICOMTag(DC::PatientID), vtkDICOMTag(DC::PatientBirthDate),
        vtkDICOMTag(DC::PatientSex), vtkDICOMTag(DC::StudyInstanceUID), vtkDICOMTag(DC::StudyDate),
        vtkDICOMTag(DC::StudyTime), vtkDICOMTag(DC::StudyID), vtkDICOMTag(DC::AccessionNumber),
        vtkDICOMTag(DC::ReferringPhysicianName), vtkDICOMTag(DC::Manufacturer),
        vtkDICOMTag(DC::KVP), vtkDICOMTag(DC::PatientPosition),
        vtkDICOMTag(DC::BodyPartExamined)}) {
    const vtkDICOMValue& v = md->Get(0, tag);
    if (v.IsValid()) src.shared_tags->Set(tag, v);
  }
  return src;
}

SourceVolume ctHeadSmall() {
  const fs::path folder = fs::path(VH_SHARED_DATASETS_DIR) / "ct/ct-head-small";
  if (!fs::exists(folder)) throw std::runtime_error("shared dataset missing: " + folder.string());
  return readSourceSeries(folder);
}

SourceVolume ballVolume(const Eigen::Vector3i& dims, const Eigen::Vector3d& spacing_mm,
                        const Eigen::Vector3d& origin_lps_mm, const Eigen::Vector3d& centre_lps_mm,
                        double radius_mm, short value, short background) {
  SourceVolume src;
  src.image = vtkSmartPointer<vtkImageData>::New();
  src.image->SetDimensions(dims.x(), dims.y(), dims.z());
  src.image->AllocateScalars(VTK_SHORT, 1);
  auto* p = static_cast<short*>(src.image->GetScalarPointer());
  for (int k = 0; k < dims.z(); ++k)
    for (int j = 0; j < dims.y(); ++j)
      for (int i = 0; i < dims.x(); ++i) {
        const Eigen::Vector3d x = origin_lps_mm + spacing_mm.cwiseProduct(Eigen::Vector3d(i, j, k));
        *p++ = (x - centre_lps_mm).norm() <= radius_mm ? value : background;
      }
  src.ijk_to_lps_mm.setIdentity();
  src.ijk_to_lps_mm.topLeftCorner<3, 3>() = spacing_mm.asDiagonal();
  src.ijk_to_lps_mm.topRightCorner<3, 1>() = origin_lps_mm;
  return src;
}

SourceVolume paddedInPlane(const SourceVolume& src, int pad) {
  int d[3];
  src.image->GetDimensions(d);
  SourceVolume out = src;
  out.image = vtkSmartPointer<vtkImageData>::New();
  out.image->SetDimensions(d[0] + 2 * pad, d[1] + 2 * pad, d[2]);
  out.image->AllocateScalars(VTK_SHORT, 1);
  const double background = src.image->GetScalarRange()[0];
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1] + 2 * pad; ++j)
      for (int i = 0; i < d[0] + 2 * pad; ++i) {
        const bool inside = i >= pad && i < d[0] + pad && j >= pad && j < d[1] + pad;
        out.image->SetScalarComponentFromDouble(
            i, j, k, 0, inside ? src.image->GetScalarComponentAsDouble(i - pad, j - pad, k, 0)
                               : background);
      }
  Eigen::Matrix4d shift = Eigen::Matrix4d::Identity();
  shift(0, 3) = -pad;
  shift(1, 3) = -pad;
  out.ijk_to_lps_mm = src.ijk_to_lps_mm * shift;
  return out;
}

double phaseScale(int t, int n) { return 1.0 + static_cast<double>(t) / std::max(n, 1); }
double echoScale(int e) { return 1.0 / (1.0 + 0.5 * e); }

WrittenSeries writeSeries(const fs::path& folder, const SourceVolume& source,
                          const SeriesSpec& spec) {
  if (spec.dicomdir) {
    throw std::runtime_error(
        "DICOMDIR not supported: vtk-dicom 0.8 only reads DICOMDIRs and neither gdcmgendir nor "
        "dcmmkdir is installed");
  }
  const bool ct = spec.modality == "CT";
  const bool pet = spec.modality == "PT";
  if (!ct && !pet && spec.modality != "MR") throw std::runtime_error("modality must be CT, MR or PT");
  if (pet && spec.multi_frame) throw std::runtime_error("PT: single-frame files only");
  if (!source.image) throw std::runtime_error("no source image");
  if (spec.time_points < 1 || spec.echoes < 1 || spec.subsample < 1) {
    throw std::runtime_error("time_points, echoes and subsample must be >= 1");
  }
  if (spec.multi_frame && (spec.time_points > 1 || spec.echoes > 1 ||
                           !spec.duplicate_slices.empty())) {
    throw std::runtime_error("multi_frame: one 3-D stack only (no time, echoes, duplicates)");
  }
  int dims[3];
  source.image->GetDimensions(dims);
  const int nx = dims[0], ny = dims[1], nz = dims[2], s = spec.subsample;

  // Geometry: u, v, w the source's unit axes, then the tilt, then the oblique rotation.
  const Eigen::Matrix3d A = source.ijk_to_lps_mm.topLeftCorner<3, 3>();
  const Eigen::Vector3d o = source.ijk_to_lps_mm.topRightCorner<3, 1>();
  const double dx = A.col(0).norm(), dy = A.col(1).norm(), dz = A.col(2).norm();
  const Eigen::Vector3d u = A.col(0) / dx, v = A.col(1) / dy, w = A.col(2) / dz;
  const double tilt = spec.gantry_tilt_deg * M_PI / 180.0;
  Eigen::Vector3d row = u, col = v, stack = dz * w;
  if (spec.tilt_convention == TiltConvention::kTiltedPlane) {
    col = std::cos(tilt) * v + std::sin(tilt) * w;
  } else {
    stack = dz * (w + std::tan(tilt) * v);
  }
  row = spec.oblique * row;
  col = spec.oblique * col;
  stack = spec.oblique * stack;

  WrittenSeries out;
  out.folder = folder;
  out.source_ijk_to_lps_mm.setIdentity();
  out.source_ijk_to_lps_mm.block<3, 1>(0, 0) = dx * row;
  out.source_ijk_to_lps_mm.block<3, 1>(0, 1) = dy * col;
  out.source_ijk_to_lps_mm.block<3, 1>(0, 2) = stack;
  out.source_ijk_to_lps_mm.block<3, 1>(0, 3) = o;
  out.normal_lps = row.cross(col).normalized();
  out.slice_jitter_mm.assign(nz, 0.0);
  for (const auto& [k, d] : spec.jitter_slices) {
    if (k >= 0 && k < nz) out.slice_jitter_mm[k] += d;
  }
  for (int k = 0; k < nz; ++k) out.slice_position_lps_mm.push_back(out.voxelLps(0, 0, k));
  out.columns = (nx + s - 1) / s;
  out.rows = (ny + s - 1) / s;
  out.subsample = s;

  // Files in writing order: time points, echoes, then slices (a duplicate right after its slice).
  std::vector<Slot> slice_slots;
  for (int t = 0; t < spec.time_points; ++t)
    for (int e = 0; e < spec.echoes; ++e)
      for (int k = 0; k < nz; ++k) {
        if (contains(spec.drop_slices, k)) continue;
        slice_slots.push_back({k, t, e});
        if (contains(spec.duplicate_slices, k)) slice_slots.push_back({k, t, e});
      }
  if (slice_slots.empty()) throw std::runtime_error("every slice dropped");

  // The staging image: one z-slice per slot, stored values scaled per phase and echo.
  auto staging = vtkSmartPointer<vtkImageData>::New();
  staging->SetDimensions(out.columns, out.rows, static_cast<int>(slice_slots.size()));
  staging->SetSpacing(s * dx, s * dy, 1.0);
  staging->AllocateScalars(VTK_SHORT, 1);
  auto* dst = static_cast<short*>(staging->GetScalarPointer());
  for (const Slot& slot : slice_slots) {
    const double f = phaseScale(slot.t, spec.time_points) * echoScale(slot.e);
    for (int j = 0; j < ny; j += s)
      for (int i = 0; i < nx; i += s) {
        const double x = std::round(f * source.image->GetScalarComponentAsDouble(i, j, slot.k, 0));
        *dst++ = static_cast<short>(std::clamp(x, -32768.0, 32767.0));
      }
  }

  // Tags the generators copy (their "source" metadata): one instance, no geometry.
  auto tags = vtkSmartPointer<vtkDICOMMetaData>::New();
  if (source.shared_tags) tags->DeepCopy(source.shared_tags);  // one instance
  tags->Set(DC::Modality, spec.modality);
  tags->Set(DC::SeriesNumber, spec.series_number);
  tags->Set(DC::SeriesDescription, spec.series_description);
  tags->Set(DC::ImageType, ct ? "ORIGINAL\\PRIMARY\\AXIAL" : "ORIGINAL\\PRIMARY\\M\\ND");
  if (!tags->Has(DC::PatientName)) tags->Set(DC::PatientName, "Fixture^Synthetic");
  if (!tags->Has(DC::PatientID)) tags->Set(DC::PatientID, "VH-FIXTURE");
  if (!tags->Has(DC::Manufacturer)) tags->Set(DC::Manufacturer, "VolumeHaptics fixtures");
  if (ct) tags->Set(DC::GantryDetectorTilt, spec.gantry_tilt_deg);

  const std::string sop_enhanced =
      ct ? "1.2.840.10008.5.1.4.1.1.2.1" : "1.2.840.10008.5.1.4.1.1.4.1";
  const Patch patch = [&](vtkDICOMMetaData* meta, vtkIntArray* slice_index) {
    if (!spec.series_uid.empty()) meta->Set(DC::SeriesInstanceUID, spec.series_uid);
    meta->Set(DC::SliceThickness, dz * std::abs(w.dot(out.normal_lps)));
    if (spec.time_points > 1) meta->Set(DC::NumberOfTemporalPositions, spec.time_points);
    if (spec.multi_frame) {
      const int frames = slice_index->GetNumberOfComponents();
      meta->Set(DC::SOPClassUID, sop_enhanced);
      meta->Set(DC::MediaStorageSOPClassUID, sop_enhanced);
      meta->Set(DC::NumberOfFrames, frames);
      meta->Set(DC::ImageType, ct ? "ORIGINAL\\PRIMARY\\AXIAL\\NONE" : "ORIGINAL\\PRIMARY\\M\\NONE");
      vtkDICOMItem measures, plane, transform, shared;
      measures.Set(DC::PixelSpacing, meta->Get(DC::PixelSpacing));
      measures.Set(DC::SliceThickness, meta->Get(DC::SliceThickness));
      plane.Set(DC::ImageOrientationPatient, orientation(row, col));
      shared.Set(DC::PixelMeasuresSequence, sequenceOf(measures));
      shared.Set(DC::PlaneOrientationSequence, sequenceOf(plane));
      if (ct) {
        transform.Set(DC::RescaleIntercept, source.rescale_intercept);
        transform.Set(DC::RescaleSlope, source.rescale_slope);
        transform.Set(DC::RescaleType, "HU");
        shared.Set(DC::PixelValueTransformationSequence, sequenceOf(transform));
      }
      vtkDICOMSequence per_frame;
      for (int f = 0; f < frames; ++f) {
        const Slot& slot = slice_slots[slice_index->GetComponent(0, f)];
        vtkDICOMItem position, content, frame;
        position.Set(DC::ImagePositionPatient, ds(out.slice_position_lps_mm[slot.k]));
        content.Set(DC::StackID, "1");
        content.Set(DC::InStackPositionNumber, f + 1);
        frame.Set(DC::PlanePositionSequence, sequenceOf(position));
        frame.Set(DC::FrameContentSequence, sequenceOf(content));
        per_frame.AddItem(frame);
      }
      meta->Set(DC::SharedFunctionalGroupsSequence, sequenceOf(shared));
      meta->Set(DC::PerFrameFunctionalGroupsSequence, vtkDICOMValue(per_frame));
      for (vtkDICOMTag tag : {vtkDICOMTag(DC::ImagePositionPatient),
                              vtkDICOMTag(DC::ImageOrientationPatient), vtkDICOMTag(DC::PixelSpacing),
                              vtkDICOMTag(DC::SliceThickness), vtkDICOMTag(DC::SliceLocation),
                              vtkDICOMTag(DC::RescaleIntercept), vtkDICOMTag(DC::RescaleSlope),
                              vtkDICOMTag(DC::RescaleType)}) {
        meta->Erase(tag);
      }
      return true;
    }
    for (int i = 0; i < meta->GetNumberOfInstances(); ++i) {
      const Slot& slot = slice_slots[slice_index->GetComponent(i, 0)];
      const Eigen::Vector3d& p = out.slice_position_lps_mm[slot.k];
      meta->Set(i, DC::InstanceNumber, i + 1);
      meta->Set(i, DC::ImagePositionPatient, ds(p));
      meta->Set(i, DC::ImageOrientationPatient, orientation(row, col));
      meta->Set(i, DC::SliceLocation, p.dot(out.normal_lps));
      if (spec.time_points > 1) {
        meta->Set(i, DC::TemporalPositionIdentifier, slot.t + 1);
        meta->Set(i, DC::TriggerTime, 100.0 * slot.t);
        meta->Set(i, DC::AcquisitionNumber, slot.t + 1);
      }
      if (spec.modality == "MR") {
        meta->Set(i, DC::EchoTime, 10.0 * (slot.e + 1));
        meta->Set(i, DC::EchoNumbers, slot.e + 1);
      }
      if (pet) {
        meta->Set(i, DC::Modality, "PT");
        meta->Set(i, DC::SOPClassUID, kPetImageStorage);
        meta->Set(i, DC::MediaStorageSOPClassUID, kPetImageStorage);
        meta->Set(i, DC::ImageType, "ORIGINAL\\PRIMARY");
      }
      if (spec.instance_tags) spec.instance_tags(meta, i, slot.k);
    }
    return true;
  };

  auto writer = vtkSmartPointer<vtkDICOMWriter>::New();
  vtkSmartPointer<vtkDICOMGenerator> generator;
  if (ct) {
    auto g = vtkSmartPointer<FixtureCTGenerator>::New();
    g->patch = patch;
    generator = g;
  } else {
    auto g = vtkSmartPointer<FixtureMRGenerator>::New();
    g->patch = patch;
    generator = g;
  }
  fs::create_directories(folder);
  std::string prefix = spec.file_prefix;
  if (prefix.empty()) prefix = std::string("S").append(std::to_string(spec.series_number)).append("_");
  writer->SetInputData(staging);
  writer->SetGenerator(generator);
  writer->SetMetaData(tags);
  writer->SetSeriesDescription(spec.series_description.c_str());
  writer->SetRescaleSlope(source.rescale_slope);
  writer->SetRescaleIntercept(source.rescale_intercept);
  writer->SetMemoryRowOrderToTopDown();  // staging row 0 is file row 0
  writer->SetFileSliceOrderToSame();      // staging slice n is file (or frame) n
  writer->SetFileDimensionality(spec.multi_frame ? 3 : 2);
  writer->SetFilePrefix((folder / prefix).string().c_str());
  writer->SetFilePattern("%s%04d.dcm");
  writer->Write();
  if (writer->GetErrorCode() != 0) {
    throw std::runtime_error(folder.string() + ": vtkDICOMWriter failed (error code " +
                             std::to_string(writer->GetErrorCode()) + ")");
  }
  vtkDICOMMetaData* written = generator->GetMetaData();
  out.series_uid = written->Get(DC::SeriesInstanceUID).AsString();
  for (int n = 0; n < written->GetNumberOfInstances(); ++n) {
    char name[32];
    std::snprintf(name, sizeof(name), "%04d.dcm", n + 1);
    out.files.push_back(folder / (prefix + name));
    if (!fs::exists(out.files.back())) {
      throw std::runtime_error(out.files.back().string() + ": not written");
    }
  }
  return out;
}

Eigen::Vector3d landmarkLps(const SourceVolume& source, const WrittenSeries& series,
                            double threshold_stored) {
  int dims[3];
  source.image->GetDimensions(dims);
  const int s = std::max(1, series.subsample);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (int k = 0; k < dims[2]; ++k)
    for (int j = 0; j < dims[1]; j += s)
      for (int i = 0; i < dims[0]; i += s) {
        const double value = source.image->GetScalarComponentAsDouble(i, j, k, 0);
        if (value <= threshold_stored) continue;
        sum += (value - threshold_stored) * series.voxelLps(i, j, k);
        weight += value - threshold_stored;
      }
  if (weight <= 0.0) throw std::runtime_error("landmarkLps: no voxel above the threshold");
  return sum / weight;
}

}  // namespace vh::io::test
