// MetaImage (.mha / .mhd) loading.
//
// vtkMetaImageReader reads the voxels. It ignores TransformMatrix (the axes' directions), and a
// short uncompressed data file gives it garbage, so the text header is parsed here as well for
// the directions and for a size check before VTK reads the data. The header is also where
// hostile files are stopped before VTK sees them: vtkmetaio expands an ElementDataFile holding
// '%' as a printf format (its list format, "name%03d.raw 1 10 1"), so "%s%n" from a file would
// reach sprintf: refused here; detached data files must lie beside the header and be regular
// files; spacings must be positive; and the declared voxels must fit in memory.
#include <fstream>
#include <map>

#include <Eigen/Core>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkMetaImageReader.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>

#include "loader_internal.h"
#include "reader_checks.h"
#include "vtk_error_capture.h"

namespace vh::io::detail {
namespace {

struct MetaHeader {
  std::map<std::string, std::string> fields;  // key as written -> trimmed value
  std::uintmax_t header_bytes = 0;            // offset after the ElementDataFile line
};

MetaHeader readHeader(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot be opened for reading");
  MetaHeader h;
  std::string line;
  std::uintmax_t offset = 0;
  std::size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    offset += line.size() + (in.eof() ? 0 : 1);
    if (line.size() > (1u << 16) || line_no > 10000) fail(path, "malformed MetaImage header");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (trim(line).empty()) continue;
    const auto eq = line.find('=');
    if (eq == std::string::npos) {
      fail(path, "malformed MetaImage header line " + std::to_string(line_no) + ": \"" + line +
                     "\"");
    }
    if (eq > 200) fail(path, "malformed MetaImage header line " + std::to_string(line_no) + " (a key of over 200 characters)");  // vtkmetaio copies keys into 255 bytes
    const std::string key = trim(line.substr(0, eq));
    h.fields[key] = trim(line.substr(eq + 1));
    if (key == "ElementDataFile") {
      h.header_bytes = offset;
      return h;
    }
  }
  fail(path, "MetaImage header has no ElementDataFile entry (not a MetaImage, or truncated)");
}

std::string get(const MetaHeader& h, const std::string& key) {
  const auto it = h.fields.find(key);
  return it == h.fields.end() ? std::string() : it->second;
}

std::size_t metaTypeSize(const std::string& t) {
  static const std::map<std::string, std::size_t> kSizes = {
      {"MET_CHAR", 1},  {"MET_UCHAR", 1}, {"MET_SHORT", 2},     {"MET_USHORT", 2},
      {"MET_INT", 4},   {"MET_UINT", 4},  {"MET_LONG", 4},      {"MET_ULONG", 4},
      {"MET_LONG_LONG", 8}, {"MET_ULONG_LONG", 8}, {"MET_FLOAT", 4}, {"MET_DOUBLE", 8}};
  const auto it = kSizes.find(t);
  return it == kSizes.end() ? 0 : it->second;
}

std::vector<double> numbers(const std::string& value, const fs::path& path,
                            const std::string& key) {
  std::vector<double> out;
  for (const auto& w : splitWords(value)) {
    const auto d = parseDouble(w);
    if (!d) fail(path, "MetaImage " + key + " has a non-numeric value: \"" + value + "\"");
    out.push_back(*d);
  }
  return out;
}

bool isTrue(const std::string& v) {
  const std::string t = toLower(v);
  return t == "true" || t == "1" || t == "yes";
}

/// The voxel count and the bytes of one voxel that a MetaImage header declares.
struct MetaLayout {
  std::uintmax_t voxel_count = 1;
  std::size_t type_size = 0;
};

/// The header's voxel layout: 3-D, sizes in [1, 2^20], a known ElementType, one channel.
/// @throws LoadError naming `path` otherwise.
MetaLayout metaLayout(const MetaHeader& h, const fs::path& path) {
  const auto ndims = parseInt(get(h, "NDims"));
  if (!ndims) fail(path, "MetaImage header has no valid NDims");
  if (*ndims != 3) {
    fail(path, "is a " + std::to_string(*ndims) +
                   "-D MetaImage; only 3-D scalar volumes are supported");
  }
  const auto dim_size = numbers(get(h, "DimSize"), path, "DimSize");
  if (dim_size.size() != 3) fail(path, "MetaImage DimSize must list 3 sizes");
  MetaLayout layout;
  for (double d : dim_size) {
    if (!(d >= 1.0 && d <= 1048576.0)) fail(path, "MetaImage DimSize has an invalid size");  // also keeps the cast and the product in range
    layout.voxel_count *= static_cast<std::uintmax_t>(d);
  }
  const std::string type = get(h, "ElementType");
  layout.type_size = metaTypeSize(type);
  if (layout.type_size == 0) fail(path, "unsupported MetaImage ElementType \"" + type + "\"");
  const auto channels = parseInt(get(h, "ElementNumberOfChannels")).value_or(1);
  if (channels != 1) {
    fail(path, "has " + std::to_string(channels) +
                   " channels per voxel; only scalar volumes are supported");
  }
  return layout;
}

/// "ElementDataFile = LIST": the file names follow the header, one per line; each must be a
/// regular file beside the header. @throws LoadError naming `path` otherwise.
void checkListedFiles(const MetaHeader& h, const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(h.header_bytes));
  std::string line;
  for (int n = 0; std::getline(in, line) && n < 100000; ++n) {
    const std::string name = trim(line);
    if (name.empty()) continue;
    fs::path file(name);
    if (file.is_relative()) file = path.parent_path() / file;
    requireBesideHeader(path, file);
    requireRegularFile(file, path);
  }
}

/// One data file (attached "LOCAL" or detached, then a regular file beside the header): it
/// exists and holds the declared voxels (uncompressed) or CompressedDataSize bytes (compressed)
/// after the header and HeaderSize. @throws LoadError naming `path` otherwise.
void checkDataFileSize(const MetaHeader& h, const fs::path& path, const std::string& data_file,
                       const MetaLayout& layout) {
  const bool compressed = isTrue(get(h, "CompressedData"));
  const bool local = data_file == "LOCAL" || data_file == "Local" || data_file == "local";
  fs::path file = local ? path : fs::path(data_file);
  if (!local && file.is_relative()) file = path.parent_path() / file;
  if (!local) {
    requireBesideHeader(path, file);
    requireRegularFile(file, path);
  }
  const auto size = fileSize(file);
  if (!size) fail(path, "data file " + file.string() + " is missing");
  std::uintmax_t start = local ? h.header_bytes : 0;
  const long long header_size = parseInt(get(h, "HeaderSize")).value_or(0);
  if (header_size > 0) start += static_cast<std::uintmax_t>(header_size);
  const std::uintmax_t available = *size > start ? *size - start : 0;
  if (!compressed) {
    const std::uintmax_t expected = layout.voxel_count * layout.type_size;
    if (available < expected) {
      fail(path, "truncated: expected " + std::to_string(expected) +
                     " bytes of voxel data" +
                     (local ? std::string() : " in " + file.filename().string()) + ", found " +
                     std::to_string(available));
    }
  } else if (const std::string declared = get(h, "CompressedDataSize"); !declared.empty()) {
    // vtkmetaio allocates what it declares before reading: a count it cannot hold (67 digits
    // became a 2^63-byte request) is refused here, as a larger one than the file has.
    const auto csize = parseInt(declared);
    if (!csize || *csize < 1) fail(path, "MetaImage CompressedDataSize is not a byte count (\"" + declared.substr(0, 40) + "\")");
    if (static_cast<std::uintmax_t>(*csize) > available)
      fail(path, "truncated: expected " + std::to_string(*csize) + " bytes of compressed voxel data, found " +
                     std::to_string(available));
  }
}

/// The data files before VTK reads them: the declared voxels fit in memory, no file-name
/// pattern (vtkmetaio would expand it as a printf format), and the listed or single data file
/// checked. @throws LoadError naming `path` otherwise.
void checkDataFiles(const MetaHeader& h, const fs::path& path, const MetaLayout& layout) {
  // Size check for an uncompressed single data file (attached "LOCAL" or detached).
  requireDeclaredFits(path, static_cast<std::uint64_t>(layout.voxel_count) * layout.type_size);
  const std::string data_file = get(h, "ElementDataFile");
  if (data_file.find('%') != std::string::npos) {
    fail(path, "ElementDataFile names a file-name pattern (\"" + data_file +
                   "\"): MetaImage's list format with a pattern is not supported; list the files with "
                   "\"ElementDataFile = LIST\" or use one data file");
  }
  const bool list = splitWords(data_file).size() >= 1 && splitWords(data_file)[0] == "LIST";
  if (list) checkListedFiles(h, path);
  else checkDataFileSize(h, path, data_file, layout);
}

/// ElementSpacing (else ElementSize, else 1 1 1) [mm]: 3 positive numbers.
/// @throws LoadError naming `path` otherwise.
std::vector<double> metaSpacing(const MetaHeader& h, const fs::path& path) {
  std::vector<double> spacing = numbers(get(h, "ElementSpacing"), path, "ElementSpacing");
  if (spacing.empty()) spacing = numbers(get(h, "ElementSize"), path, "ElementSize");
  if (spacing.empty()) spacing = {1.0, 1.0, 1.0};
  if (spacing.size() != 3) fail(path, "MetaImage ElementSpacing must list 3 values");
  for (const double s : spacing) {
    // numbers() already refused "nan" and "inf"; a zero or negative spacing would load at a
    // size, or mirrored, that the file does not mean.
    if (!(s > 0.0)) {
      fail(path, "MetaImage ElementSpacing must be 3 positive numbers, found \"" +
                     (get(h, "ElementSpacing").empty() ? get(h, "ElementSize") : get(h, "ElementSpacing")) + "\"");
    }
  }
  return spacing;
}

/// The voxels as vtkMetaImageReader reads them. @throws LoadError naming `path` when it reports
/// an error or reads no scalars.
vtkSmartPointer<vtkImageData> readMetaVoxels(const fs::path& path) {
  VtkErrorCapture capture;
  auto reader = vtkSmartPointer<vtkMetaImageReader>::New();
  capture.watch(reader);
  reader->SetFileName(path.string().c_str());
  reader->Update();
  if (capture.hasErrors()) {
    fail(path, "voxel data could not be read (" + capture.firstError() + ")");
  }
  vtkImageData* out = reader->GetOutput();
  if (out == nullptr || out->GetPointData()->GetScalars() == nullptr) {
    fail(path, "no voxel data was read");
  }
  return out;
}

/// The grid's origin (Offset, else Position, else Origin, else 0) [mm].
/// @throws LoadError naming `path` when it does not list 3 values.
std::vector<double> metaOrigin(const MetaHeader& h, const fs::path& path) {
  std::vector<double> origin;
  for (const char* key : {"Offset", "Position", "Origin"}) {
    origin = numbers(get(h, key), path, key);
    if (!origin.empty()) break;
  }
  if (origin.empty()) origin = {0.0, 0.0, 0.0};
  if (origin.size() != 3) fail(path, "MetaImage Offset must list 3 values");
  return origin;
}

/// The grid axes' directions (TransformMatrix, else Rotation, else Orientation, else the
/// identity; its rows are the axes), columns scaled by `spacing` [mm].
/// @throws LoadError naming `path` when the matrix does not hold 9 values.
Eigen::Matrix3d metaAxes(const MetaHeader& h, const fs::path& path, const std::vector<double>& spacing) {
  std::vector<double> matrix;
  for (const char* key : {"TransformMatrix", "Rotation", "Orientation"}) {
    matrix = numbers(get(h, key), path, key);
    if (!matrix.empty()) break;
  }
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  if (!matrix.empty()) {
    if (matrix.size() != 9) fail(path, "MetaImage TransformMatrix must hold 9 values");
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) axes(r, c) = matrix[static_cast<std::size_t>(3 * c + r)];
    }
  }
  for (int c = 0; c < 3; ++c) axes.col(c) *= spacing[static_cast<std::size_t>(c)];
  return axes;
}

}  // namespace

LoadedVolume loadMetaImage(const fs::path& path) {
  const MetaHeader h = readHeader(path);
  const MetaLayout layout = metaLayout(h, path);
  checkDataFiles(h, path, layout);
  // The spacing before VTK reads (VTK cannot parse "nan" and would say only that).
  const std::vector<double> spacing = metaSpacing(h, path);
  vtkSmartPointer<vtkImageData> out = readMetaVoxels(path);

  // Geometry: MetaImage coordinates are millimetres in the file's world frame (patient LPS for
  // files written by ITK). TransformMatrix rows are the grid axes' directions.
  const std::vector<double> origin = metaOrigin(h, path);
  const Eigen::Matrix3d axes = metaAxes(h, path, spacing);
  Eigen::Matrix3d direction;
  Eigen::Vector3d spacing_mm;
  splitAxes(axes, path, direction, spacing_mm);

  RawVolume raw;
  raw.image = out;
  raw.geometry.spacing_m = spacing_mm * 1e-3;
  raw.geometry.direction_W = direction;
  raw.geometry.origin_W_m = Eigen::Vector3d(origin[0], origin[1], origin[2]) * 1e-3;
  raw.info.format = "MetaImage";
  const std::string modality = get(h, "Modality");
  if (modality.rfind("MET_MOD_", 0) == 0 && modality != "MET_MOD_UNKNOWN") {
    raw.info.modality = modality.substr(8);
  }
  if (raw.info.modality == "CT") raw.info.value_unit = "HU";
  raw.info.description = path.filename().string();
  return finishVolume(std::move(raw), path);
}

}  // namespace vh::io::detail
