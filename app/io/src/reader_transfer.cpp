// The reader process's output files: volumes, series lists and meshes written by the reader
// process and read back by the application (formats in reader_transfer.h).
#include "reader_transfer.h"

#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>
#include <stdexcept>

#include <nlohmann/json.hpp>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>

namespace vh::io::detail {
namespace {

using json = nlohmann::json;

constexpr char kMagic[] = "VHRAW1\n";
/// Largest JSON header accepted [bytes]: a damaged output file must not allocate without bound.
constexpr std::uint64_t kMaxHeaderBytes = 1u << 26;

json toJson(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d vec(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

json geometryToJson(const Eigen::Vector3d& spacing_m, const Eigen::Vector3d& origin_W_m,
                    const Eigen::Matrix3d& direction_W) {
  return {{"spacing_m", toJson(spacing_m)},
          {"origin_W_m", toJson(origin_W_m)},
          {"direction_W", {toJson(direction_W.col(0)), toJson(direction_W.col(1)), toJson(direction_W.col(2))}}};
}

/// Spacing, origin and directions of a header (dims are read by the caller).
void geometryFromJson(const json& h, haptics::VolumeGeometry& g) {
  g.spacing_m = vec(h.at("spacing_m"));
  g.origin_W_m = vec(h.at("origin_W_m"));
  for (int c = 0; c < 3; ++c) g.direction_W.col(c) = vec(h.at("direction_W").at(c));
}

/// kMagic, the JSON header's length (8 bytes) and the header; the voxels follow.
void writeHeader(std::ofstream& f, const json& h) {
  const std::string header = h.dump(-1, ' ', false, json::error_handler_t::replace);
  const std::uint64_t n = header.size();
  f.write(kMagic, sizeof(kMagic) - 1);
  f.write(reinterpret_cast<const char*>(&n), sizeof(n));
  f.write(header.data(), static_cast<std::streamsize>(header.size()));
}

/// Reads what writeHeader() wrote (a LoadError naming `source` when it cannot).
json readHeader(std::ifstream& f, const fs::path& source) {
  char magic[sizeof(kMagic) - 1];
  std::uint64_t n = 0;
  f.read(magic, sizeof(magic));
  f.read(reinterpret_cast<char*>(&n), sizeof(n));
  if (!f || std::memcmp(magic, kMagic, sizeof(magic)) != 0 || n > kMaxHeaderBytes) {
    fail(source, "the reader process's output is unreadable");
  }
  std::string header(n, '\0');
  f.read(header.data(), static_cast<std::streamsize>(n));
  try {
    return json::parse(header);
  } catch (const json::exception& e) {
    fail(source, std::string("the reader process's output is unreadable: ") + e.what());
  }
}

json infoToJson(const VolumeInfo& i) {
  return {{"format", i.format},           {"modality", i.modality},         {"value_unit", i.value_unit},
          {"description", i.description}, {"patient_name", i.patient_name}, {"series_uid", i.series_uid},
          {"series_number", i.series_number}, {"phase", i.phase},           {"phase_count", i.phase_count},
          {"frame_of_reference_uid", i.frame_of_reference_uid}, {"notices", i.notices}};
}

VolumeInfo infoFromJson(const json& i) {
  VolumeInfo info;
  info.format = i.at("format").get<std::string>();
  info.modality = i.at("modality").get<std::string>();
  info.value_unit = i.at("value_unit").get<std::string>();
  info.description = i.at("description").get<std::string>();
  info.patient_name = i.at("patient_name").get<std::string>();
  info.series_uid = i.at("series_uid").get<std::string>();
  info.series_number = i.at("series_number").get<int>();
  info.phase = i.at("phase").get<int>();
  info.phase_count = i.at("phase_count").get<int>();
  info.frame_of_reference_uid = i.at("frame_of_reference_uid").get<std::string>();
  info.notices = i.at("notices").get<std::vector<std::string>>();
  return info;
}

json seriesToJson(const DicomSeriesInfo& i) {
  std::vector<std::string> files;
  for (const auto& f : i.files) files.push_back(f.string());
  return {{"folder", i.folder.string()},
          {"index", i.index},
          {"patient_name", i.patient_name},
          {"patient_id", i.patient_id},
          {"study_description", i.study_description},
          {"study_date", i.study_date},
          {"series_description", i.series_description},
          {"series_uid", i.series_uid},
          {"series_number", i.series_number},
          {"modality", i.modality},
          {"file_count", i.file_count},
          {"slice_count", i.slice_count},
          {"rows", i.rows},
          {"columns", i.columns},
          {"spacing_mm", toJson(i.spacing_mm)},
          {"files", files}};
}

DicomSeriesInfo seriesFromJson(const json& j) {
  DicomSeriesInfo i;
  i.folder = j.at("folder").get<std::string>();
  i.index = j.at("index").get<int>();
  i.patient_name = j.at("patient_name").get<std::string>();
  i.patient_id = j.at("patient_id").get<std::string>();
  i.study_description = j.at("study_description").get<std::string>();
  i.study_date = j.at("study_date").get<std::string>();
  i.series_description = j.at("series_description").get<std::string>();
  i.series_uid = j.at("series_uid").get<std::string>();
  i.series_number = j.at("series_number").get<int>();
  i.modality = j.at("modality").get<std::string>();
  i.file_count = j.at("file_count").get<int>();
  i.slice_count = j.at("slice_count").get<int>();
  i.rows = j.at("rows").get<int>();
  i.columns = j.at("columns").get<int>();
  i.spacing_mm = vec(j.at("spacing_mm"));
  for (const auto& f : j.at("files")) i.files.emplace_back(f.get<std::string>());
  return i;
}

json segmentToJson(const DicomSegSegment& s) {
  return {{"number", s.number}, {"label", s.label}, {"category", s.category}, {"type", s.type},
          {"has_lab", s.has_lab}, {"lab", s.lab},     {"rgb", s.rgb}};
}

DicomSegSegment segmentFromJson(const json& j) {
  DicomSegSegment s;
  s.number = j.at("number").get<int>();
  s.label = j.at("label").get<std::string>();
  s.category = j.at("category").get<std::string>();
  s.type = j.at("type").get<std::string>();
  s.has_lab = j.at("has_lab").get<bool>();
  s.lab = j.at("lab").get<std::array<int, 3>>();
  s.rgb = j.at("rgb").get<std::array<double, 3>>();
  return s;
}

json framePlaneToJson(const DicomSegFrame& f) {
  return {{"segment", f.segment},
          {"position_mm", toJson(f.position_mm)},
          {"row_dir", toJson(f.row_dir)},
          {"col_dir", toJson(f.col_dir)},
          {"row_spacing_mm", f.row_spacing_mm},
          {"column_spacing_mm", f.column_spacing_mm}};
}

DicomSegFrame framePlaneFromJson(const json& j) {
  DicomSegFrame f;
  f.segment = j.at("segment").get<int>();
  f.position_mm = vec(j.at("position_mm"));
  f.row_dir = vec(j.at("row_dir"));
  f.col_dir = vec(j.at("col_dir"));
  f.row_spacing_mm = j.at("row_spacing_mm").get<double>();
  f.column_spacing_mm = j.at("column_spacing_mm").get<double>();
  return f;
}

}  // namespace

void writeDicomSeg(const DicomSegFile& seg, const fs::path& out) {
  json h = {{"series_uid", seg.series_uid},
            {"frame_of_reference_uid", seg.frame_of_reference_uid},
            {"referenced_series_uids", seg.referenced_series_uids},
            {"fractional", seg.fractional},
            {"rows", seg.rows},
            {"columns", seg.columns},
            {"slice_thickness_mm", seg.slice_thickness_mm},
            {"spacing_between_slices_mm", seg.spacing_between_slices_mm},
            {"notices", seg.notices}};
  h["segments"] = json::array();
  for (const auto& s : seg.segments) h["segments"].push_back(segmentToJson(s));
  h["frames"] = json::array();
  for (const auto& f : seg.frames) h["frames"].push_back(framePlaneToJson(f));
  std::ofstream f(out, std::ios::binary);
  writeHeader(f, h);
  for (const auto& frame : seg.frames) {
    f.write(reinterpret_cast<const char*>(frame.mask.data()), static_cast<std::streamsize>(frame.mask.size()));
  }
  if (!f) throw LoadError(out.string() + ": cannot write the DICOM SEG read (disk full?)");
}

DicomSegFile readDicomSegTransfer(const fs::path& in, const fs::path& source) {
  std::ifstream f(in, std::ios::binary);
  const json h = readHeader(f, source);
  DicomSegFile seg;
  try {
    seg.series_uid = h.at("series_uid").get<std::string>();
    seg.frame_of_reference_uid = h.at("frame_of_reference_uid").get<std::string>();
    seg.referenced_series_uids = h.at("referenced_series_uids").get<std::vector<std::string>>();
    seg.fractional = h.at("fractional").get<bool>();
    seg.rows = h.at("rows").get<int>();
    seg.columns = h.at("columns").get<int>();
    seg.slice_thickness_mm = h.at("slice_thickness_mm").get<double>();
    seg.spacing_between_slices_mm = h.at("spacing_between_slices_mm").get<double>();
    seg.notices = h.at("notices").get<std::vector<std::string>>();
    for (const auto& s : h.at("segments")) seg.segments.push_back(segmentFromJson(s));
    if (seg.rows < 1 || seg.columns < 1 || seg.rows > 65535 || seg.columns > 65535) {
      fail(source, "the reader process's output is invalid: frames of " + std::to_string(seg.columns) + " x " +
                       std::to_string(seg.rows) + " pixels");
    }
    const std::size_t bytes = maskBytes(static_cast<std::size_t>(seg.rows) * static_cast<std::size_t>(seg.columns));
    for (const auto& j : h.at("frames")) {
      DicomSegFrame frame = framePlaneFromJson(j);
      frame.mask.resize(bytes);
      f.read(reinterpret_cast<char*>(frame.mask.data()), static_cast<std::streamsize>(bytes));
      if (static_cast<std::size_t>(f.gcount()) != bytes) fail(source, "the reader process's output is cut short");
      seg.frames.push_back(std::move(frame));
    }
  } catch (const json::exception& e) {
    fail(source, std::string("the reader process's output is unreadable: ") + e.what());
  }
  return seg;
}

void writeDicomRtStruct(const RtStructFile& rs, const fs::path& out) {
  json h = {{"series_uid", rs.series_uid},
            {"frame_of_reference_uids", rs.frame_of_reference_uids},
            {"referenced_series_uids", rs.referenced_series_uids},
            {"notices", rs.notices}};
  h["rois"] = json::array();
  for (const auto& roi : rs.rois) {
    json contours = json::array();
    for (const auto& c : roi.contours) {
      std::vector<double> xyz;  // x\y\z per point, LPS [mm]
      for (const auto& p : c.points_mm) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
      contours.push_back({{"type", c.type}, {"points_mm", xyz}});
    }
    h["rois"].push_back({{"number", roi.number},
                         {"name", roi.name},
                         {"frame_of_reference_uid", roi.frame_of_reference_uid},
                         {"has_color", roi.has_color},
                         {"color", roi.color},
                         {"contours", contours}});
  }
  std::ofstream f(out, std::ios::binary);
  writeHeader(f, h);
  if (!f) throw LoadError(out.string() + ": cannot write the RT Structure Set read (disk full?)");
}

RtStructFile readDicomRtStructTransfer(const fs::path& in, const fs::path& source) {
  std::ifstream f(in, std::ios::binary);
  const json h = readHeader(f, source);
  RtStructFile rs;
  try {
    rs.series_uid = h.at("series_uid").get<std::string>();
    rs.frame_of_reference_uids = h.at("frame_of_reference_uids").get<std::vector<std::string>>();
    rs.referenced_series_uids = h.at("referenced_series_uids").get<std::vector<std::string>>();
    rs.notices = h.at("notices").get<std::vector<std::string>>();
    for (const auto& j : h.at("rois")) {
      RtStructRoi roi;
      roi.number = j.at("number").get<int>();
      roi.name = j.at("name").get<std::string>();
      roi.frame_of_reference_uid = j.at("frame_of_reference_uid").get<std::string>();
      roi.has_color = j.at("has_color").get<bool>();
      roi.color = j.at("color").get<std::array<int, 3>>();
      for (const auto& c : j.at("contours")) {
        RtStructContour contour;
        contour.type = c.at("type").get<std::string>();
        const auto xyz = c.at("points_mm").get<std::vector<double>>();
        if (xyz.size() % 3 != 0) fail(source, "the reader process's output is invalid: contour data not in triples");
        for (std::size_t p = 0; p + 2 < xyz.size(); p += 3) {
          contour.points_mm.emplace_back(xyz[p], xyz[p + 1], xyz[p + 2]);
        }
        roi.contours.push_back(std::move(contour));
      }
      rs.rois.push_back(std::move(roi));
    }
  } catch (const json::exception& e) {
    fail(source, std::string("the reader process's output is unreadable: ") + e.what());
  }
  return rs;
}

void writeField(const haptics::ScalarVolume& field, const VolumeInfo& info, const fs::path& out) {
  const auto& g = field.geometry();
  json h = geometryToJson(g.spacing_m, g.origin_W_m, g.direction_W);
  h["dims"] = g.dims;
  h["voxel_type"] = static_cast<int>(field.voxelType());
  h["value_scale"] = field.valueScale();
  h["value_offset"] = field.valueOffset();
  h["info"] = infoToJson(info);
  std::ofstream f(out, std::ios::binary);
  writeHeader(f, h);
  f.write(reinterpret_cast<const char*>(field.bytes().data()), static_cast<std::streamsize>(field.bytes().size()));
  if (!f) throw LoadError(out.string() + ": cannot write the loaded volume (disk full?)");
}

LoadedVolume readField(const fs::path& in, const fs::path& source) {
  std::ifstream f(in, std::ios::binary);
  const json h = readHeader(f, source);
  LoadedVolume out;
  try {
    haptics::VolumeGeometry g;
    g.dims = h.at("dims").get<std::array<int, 3>>();
    geometryFromJson(h, g);
    const auto type = static_cast<haptics::VoxelType>(h.at("voxel_type").get<int>());
    std::vector<std::byte> bytes(g.voxelCount() * haptics::voxelTypeSize(type));
    f.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (static_cast<std::size_t>(f.gcount()) != bytes.size()) fail(source, "the reader process's output is cut short");
    out.field = std::make_shared<haptics::ScalarVolume>(haptics::ScalarVolume::FromBytes(
        g, type, std::move(bytes), h.at("value_scale").get<double>(), h.at("value_offset").get<double>()));
    out.image = imageFromField(out.field);  // the field's own voxels when they are in data units
    out.info = infoFromJson(h.at("info"));
    out.info.source = source;
  } catch (const json::exception& e) {
    fail(source, std::string("the reader process's output is unreadable: ") + e.what());
  } catch (const std::invalid_argument& e) {
    fail(source, std::string("the reader process's output is invalid: ") + e.what());
  }
  return out;
}

void writeRaw(const RawVolume& raw, const fs::path& out) {
  int dims[3];
  raw.image->GetDimensions(dims);
  vtkDataArray* scalars = raw.image->GetPointData()->GetScalars();
  if (scalars == nullptr) throw LoadError(out.string() + ": the reader produced no voxels");
  json h = geometryToJson(raw.geometry.spacing_m, raw.geometry.origin_W_m, raw.geometry.direction_W);
  h["dims"] = {dims[0], dims[1], dims[2]};
  h["components"] = scalars->GetNumberOfComponents();
  h["vtk_type"] = scalars->GetDataType();
  h["value_scale"] = raw.value_scale;
  h["value_offset"] = raw.value_offset;
  h["info"] = infoToJson(raw.info);
  std::ofstream f(out, std::ios::binary);
  writeHeader(f, h);
  const auto bytes = static_cast<std::streamsize>(scalars->GetNumberOfValues()) * scalars->GetDataTypeSize();
  f.write(static_cast<const char*>(scalars->GetVoidPointer(0)), bytes);
  if (!f) throw LoadError(out.string() + ": cannot write the loaded volume (disk full?)");
}

RawVolume readRaw(const fs::path& in, const fs::path& source) {
  std::ifstream f(in, std::ios::binary);
  const json h = readHeader(f, source);
  RawVolume raw;
  try {
    const auto dims = h.at("dims").get<std::array<int, 3>>();
    const int vtk_type = h.at("vtk_type").get<int>();
    const int components = h.at("components").get<int>();
    geometryFromJson(h, raw.geometry);
    const auto voxel_type = fieldVoxelTypeOf(vtk_type);
    if (voxel_type.has_value() && components == 1 && dims[0] > 0 && dims[1] > 0 && dims[2] > 0) {
      // Straight into the buffer the field will own (finishVolume()): no VTK image in between.
      raw.geometry.dims = dims;
      raw.voxel_type = *voxel_type;
      const std::size_t expected = raw.geometry.voxelCount() * haptics::voxelTypeSize(*voxel_type);
      std::error_code ec;
      const auto file_bytes = fs::file_size(in, ec);
      if (ec || expected > file_bytes) fail(source, "the reader process's output is cut short");
      raw.voxels.resize(expected);
      const auto bytes = static_cast<std::streamsize>(raw.voxels.size());
      f.read(reinterpret_cast<char*>(raw.voxels.data()), bytes);
      if (f.gcount() != bytes) fail(source, "the reader process's output is cut short");
    } else {
      // Other types (converted by finishVolume()) and shapes it refuses with their own message.
      raw.image = vtkSmartPointer<vtkImageData>::New();
      raw.image->SetDimensions(dims[0], dims[1], dims[2]);
      raw.image->AllocateScalars(vtk_type, components);
      vtkDataArray* scalars = raw.image->GetPointData()->GetScalars();
      const auto bytes = static_cast<std::streamsize>(scalars->GetNumberOfValues()) * scalars->GetDataTypeSize();
      f.read(static_cast<char*>(scalars->GetVoidPointer(0)), bytes);
      if (f.gcount() != bytes) fail(source, "the reader process's output is cut short");
    }
    raw.value_scale = h.at("value_scale").get<double>();
    raw.value_offset = h.at("value_offset").get<double>();
    raw.info = infoFromJson(h.at("info"));
  } catch (const json::exception& e) {
    fail(source, std::string("the reader process's output is unreadable: ") + e.what());
  }
  return raw;
}

void writeSeriesList(const std::vector<DicomSeriesInfo>& series, const fs::path& out) {
  json list = json::array();
  for (const auto& i : series) list.push_back(seriesToJson(i));
  std::ofstream(out) << list.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::vector<DicomSeriesInfo> readSeriesList(const fs::path& in, const fs::path& source) {
  std::vector<DicomSeriesInfo> series;
  try {
    std::ifstream f(in);
    for (const auto& j : json::parse(f)) series.push_back(seriesFromJson(j));
  } catch (const json::exception& e) {
    fail(source, std::string("the reader process's series list is unreadable: ") + e.what());
  }
  return series;
}

void writeMesh(const haptics::TriangleMesh& mesh, const fs::path& out, const fs::path& source) {
  std::ofstream f(out, std::ios::binary);
  const std::uint64_t nv = mesh.vertices_T_m.size(), nt = mesh.triangles.size();
  f.write(reinterpret_cast<const char*>(&nv), sizeof(nv));
  f.write(reinterpret_cast<const char*>(&nt), sizeof(nt));
  for (const auto& v : mesh.vertices_T_m) f.write(reinterpret_cast<const char*>(v.data()), 3 * sizeof(double));
  for (const auto& t : mesh.triangles) f.write(reinterpret_cast<const char*>(t.data()), 3 * sizeof(int));
  if (!f) throw LoadError(source.string() + ": cannot hand the mesh back (disk full?)");
}

haptics::TriangleMesh readMesh(const fs::path& in, const fs::path& source) {
  std::ifstream f(in, std::ios::binary);
  std::uint64_t nv = 0, nt = 0;
  f.read(reinterpret_cast<char*>(&nv), sizeof(nv));
  f.read(reinterpret_cast<char*>(&nt), sizeof(nt));
  if (!f || nv > (1ull << 31) || nt > (1ull << 31)) fail(source, "the reader process's mesh output is unreadable");
  haptics::TriangleMesh mesh;
  mesh.vertices_T_m.resize(nv);
  mesh.triangles.resize(nt);
  for (auto& v : mesh.vertices_T_m) f.read(reinterpret_cast<char*>(v.data()), 3 * sizeof(double));
  for (auto& t : mesh.triangles) f.read(reinterpret_cast<char*>(t.data()), 3 * sizeof(int));
  if (!f) fail(source, "the reader process's mesh output is cut short");
  for (const auto& t : mesh.triangles) {
    for (int v : t) {
      if (v < 0 || static_cast<std::uint64_t>(v) >= nv) {
        fail(source, "the reader process's mesh output is inconsistent");
      }
    }
  }
  return mesh;
}

}  // namespace vh::io::detail
