// NRRD (.nrrd / .nhdr) loading.
//
// vtkNrrdReader reads the voxels (raw, ascii or gzip; attached or detached; single file, LIST or
// format-string file lists of 2-D slices; big or little endian). Its quirks, handled here:
//  - it keeps only the lengths of `space directions` (as spacing) and ignores their directions
//    and the `space` / `space units` fields: the header is parsed here for the geometry;
//  - a short raw data file gives garbage, not an error: sizes are checked here first;
//  - a fastest axis of 9 voxels or fewer is taken for vector components: such images are
//    reshaped back into scalar volumes;
//  - for spaces "left-anterior-superior" / "LAS" / "3D-left-handed" the raw path flips the rows
//    (FileLowerLeft off): they are flipped back so voxel (i, j, k) is the file's voxel (i, j, k);
//  - descending format-string ranges, byte / line skips and multi-file gzip are not supported:
//    rejected here with a clear message.
#include <algorithm>
#include <bit>
#include <iterator>
#include <limits>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include <Eigen/Core>
#include <vtkDataArray.h>
#include <vtkType.h>
#include <vtkImageData.h>
#include <vtkNrrdReader.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>
#include <zlib.h>

#include "loader_internal.h"
#include "reader_checks.h"
#include "vh/io/patient_frames.h"
#include "vtk_error_capture.h"

namespace vh::io::detail {
namespace {

struct NrrdHeader {
  std::map<std::string, std::string> fields;  // lower-case key -> trimmed value
  std::map<std::string, std::string> key_values;  // "key:=value" pairs, key as written
  std::vector<fs::path> data_files;           // absolute or relative to the header's folder
  bool detached = false;
  std::uintmax_t header_bytes = 0;  // offset of attached data
};

struct NrrdType {
  std::size_t size = 0;  // bytes per value; 0 = unknown / unsupported
  int vtk_type = VTK_VOID;
};

/// Size and VTK type of a NRRD type name.
NrrdType nrrdType(const std::string& type_in) {
  const std::string t = toLower(trim(type_in));
  static const std::map<std::string, NrrdType> kTypes = {
      {"signed char", {1, VTK_SIGNED_CHAR}},       {"int8", {1, VTK_SIGNED_CHAR}},
      {"int8_t", {1, VTK_SIGNED_CHAR}},            {"uchar", {1, VTK_UNSIGNED_CHAR}},
      {"unsigned char", {1, VTK_UNSIGNED_CHAR}},   {"uint8", {1, VTK_UNSIGNED_CHAR}},
      {"uint8_t", {1, VTK_UNSIGNED_CHAR}},         {"short", {2, VTK_SHORT}},
      {"short int", {2, VTK_SHORT}},               {"signed short", {2, VTK_SHORT}},
      {"signed short int", {2, VTK_SHORT}},        {"int16", {2, VTK_SHORT}},
      {"int16_t", {2, VTK_SHORT}},                 {"ushort", {2, VTK_UNSIGNED_SHORT}},
      {"unsigned short", {2, VTK_UNSIGNED_SHORT}}, {"unsigned short int", {2, VTK_UNSIGNED_SHORT}},
      {"uint16", {2, VTK_UNSIGNED_SHORT}},         {"uint16_t", {2, VTK_UNSIGNED_SHORT}},
      {"int", {4, VTK_INT}},                       {"signed int", {4, VTK_INT}},
      {"int32", {4, VTK_INT}},                     {"int32_t", {4, VTK_INT}},
      {"uint", {4, VTK_UNSIGNED_INT}},             {"unsigned int", {4, VTK_UNSIGNED_INT}},
      {"uint32", {4, VTK_UNSIGNED_INT}},           {"uint32_t", {4, VTK_UNSIGNED_INT}},
      {"longlong", {8, VTK_TYPE_INT64}},           {"long long", {8, VTK_TYPE_INT64}},
      {"long long int", {8, VTK_TYPE_INT64}},      {"signed long long", {8, VTK_TYPE_INT64}},
      {"signed long long int", {8, VTK_TYPE_INT64}}, {"int64", {8, VTK_TYPE_INT64}},
      {"int64_t", {8, VTK_TYPE_INT64}},            {"ulonglong", {8, VTK_TYPE_UINT64}},
      {"unsigned long long", {8, VTK_TYPE_UINT64}}, {"unsigned long long int", {8, VTK_TYPE_UINT64}},
      {"uint64", {8, VTK_TYPE_UINT64}},            {"uint64_t", {8, VTK_TYPE_UINT64}},
      {"float", {4, VTK_FLOAT}},                   {"double", {8, VTK_DOUBLE}}};
  const auto it = kTypes.find(t);
  return it == kTypes.end() ? NrrdType{} : it->second;
}

/// Reads ascii-encoded voxels (white-space separated numbers) from the data file(s). Done here
/// rather than by vtkNrrdReader, whose ascii path misreads volumes whose fastest axis it takes
/// for vector components (9 voxels or fewer).
vtkSmartPointer<vtkImageData> readAscii(const NrrdHeader& h, const fs::path& path, int vtk_type,
                                        const std::array<int, 3>& sizes,
                                        std::uintmax_t voxel_count) {
  vtkSmartPointer<vtkDataArray> values;
  values.TakeReference(vtkDataArray::CreateDataArray(vtk_type));
  values->SetNumberOfComponents(1);
  values->SetNumberOfTuples(static_cast<vtkIdType>(voxel_count));
  std::vector<fs::path> files = h.data_files;
  if (files.empty()) files.push_back(path);
  vtkIdType n = 0;
  for (std::size_t f = 0; f < files.size(); ++f) {
    std::ifstream in(files[f]);
    if (!in) fail(path, "data file " + files[f].string() + " cannot be opened");
    if (!h.detached) in.seekg(static_cast<std::streamoff>(h.header_bytes));
    const auto per_file = static_cast<vtkIdType>(voxel_count / files.size());
    const vtkIdType end = f + 1 == files.size() ? static_cast<vtkIdType>(voxel_count) : n + per_file;
    double v = 0.0;
    while (n < end && (in >> v)) values->SetTuple1(n++, v);
    if (n < end) {
      if (!in.eof()) {
        fail(path, "corrupt ascii voxel data in " + files[f].filename().string() +
                       " (not a number after value " + std::to_string(n) + ")");
      }
      fail(path, "truncated: expected " + std::to_string(voxel_count) +
                     " ascii voxel values, found " + std::to_string(n));
    }
  }
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(sizes[0], sizes[1], sizes[2]);
  image->GetPointData()->SetScalars(values);
  return image;
}

/// True when the bytes at `offset` of `file` start a gzip stream.
bool startsWithGzipMagic(const fs::path& file, std::uintmax_t offset) {
  std::ifstream in(file, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(offset));
  unsigned char magic[2] = {0, 0};
  in.read(reinterpret_cast<char*>(magic), 2);
  return in.gcount() == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
}

/// Expands a NRRD data-file format string ("quarter.%d", "%03d.raw") for one number. Only one
/// integer conversion is accepted (flags '0' / '-', a width, d / i / u); "%%" is a literal.
std::optional<std::string> expandFormat(const std::string& fmt, long long value) {
  std::string out;
  bool used = false;
  for (std::size_t i = 0; i < fmt.size(); ++i) {
    if (fmt[i] != '%') {
      out += fmt[i];
      continue;
    }
    if (i + 1 < fmt.size() && fmt[i + 1] == '%') {
      out += '%';
      ++i;
      continue;
    }
    if (used) return std::nullopt;
    std::size_t j = i + 1;
    bool zero = false;
    bool left = false;
    while (j < fmt.size() && (fmt[j] == '0' || fmt[j] == '-')) {
      (fmt[j] == '0' ? zero : left) = true;
      ++j;
    }
    int width = 0;
    while (j < fmt.size() && std::isdigit(static_cast<unsigned char>(fmt[j])) != 0) {
      width = std::min(width * 10 + (fmt[j] - '0'), 64);
      ++j;
    }
    if (j >= fmt.size() || (fmt[j] != 'd' && fmt[j] != 'i' && fmt[j] != 'u')) return std::nullopt;
    std::string digits = std::to_string(value < 0 ? -value : value);
    const std::string sign = value < 0 ? "-" : "";
    std::string number = sign + digits;
    if (static_cast<int>(number.size()) < width) {
      const std::size_t pad = static_cast<std::size_t>(width) - number.size();
      if (left) {
        number += std::string(pad, ' ');
      } else if (zero) {
        number = sign + std::string(pad, '0') + digits;
      } else {
        number = std::string(pad, ' ') + number;
      }
    }
    out += number;
    used = true;
    i = j;
  }
  if (!used) return std::nullopt;
  return out;
}

/// The "data file" field's `value`: the header is detached, and its data files are one file, a
/// printf-style pattern over a range ("slice%03d.raw 1 100 1", at most `max_files`), or
/// "LIST" (the names follow, one per line). @return whether the names follow as a list.
/// @throws LoadError naming `path` for a malformed range or pattern, or too many files.
bool addDataFiles(NrrdHeader& h, const fs::path& path, const std::string& value, std::size_t max_files) {
  h.detached = true;
  const auto words = splitWords(value);
  if (!words.empty() && words[0] == "LIST") return true;
  if (value.find('%') != std::string::npos && (words.size() == 4 || words.size() == 5)) {
    const auto lo = parseInt(words[1]);
    const auto hi = parseInt(words[2]);
    const auto step = parseInt(words[3]);
    if (!lo || !hi || !step || *step == 0) {
      fail(path, "malformed \"data file\" range: \"" + value + "\"");
    }
    for (long long v = *lo; *step > 0 ? v <= *hi : v >= *hi; v += *step) {
      const auto name = expandFormat(words[0], v);
      if (!name) fail(path, "unsupported \"data file\" format string \"" + words[0] + "\"");
      h.data_files.emplace_back(*name);
      if (h.data_files.size() > max_files) fail(path, "too many data files");
    }
  } else {
    h.data_files.emplace_back(value);
  }
  return false;
}

NrrdHeader readHeader(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot be opened for reading");
  NrrdHeader h;
  std::string line;
  std::uintmax_t offset = 0;
  if (!std::getline(in, line) || line.rfind("NRRD000", 0) != 0 || line.find('\0') != std::string::npos) {
    fail(path, "not a NRRD file (the first line is not \"NRRD000x\")");
  }
  offset += line.size() + 1;
  bool in_list = false;
  bool ended = false;
  std::size_t line_no = 1;
  constexpr std::size_t kMaxLine = 1 << 16;
  constexpr std::size_t kMaxLines = 1 << 20;
  while (std::getline(in, line)) {
    ++line_no;
    const bool had_newline = !in.eof();
    offset += line.size() + (had_newline ? 1 : 0);
    if (line.size() > kMaxLine || line_no > kMaxLines) {
      fail(path, "malformed NRRD header (line " + std::to_string(line_no) + " is too long)");
    }
    if (line.find('\0') != std::string::npos) fail(path, "malformed NRRD header (a NUL byte in line " + std::to_string(line_no) + ")");  // vtkNrrdReader 9.1 loops forever on one
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (in_list) {
      const std::string name = trim(line);
      if (name.empty()) {
        ended = true;
        break;
      }
      h.data_files.emplace_back(name);
      continue;
    }
    if (line.empty()) {
      ended = true;
      break;
    }
    if (line[0] == '#') continue;
    if (const auto kv = line.find(":="); kv != std::string::npos) {  // key/value pair, not a field
      h.key_values[line.substr(0, kv)] = line.substr(kv + 2);
      continue;
    }
    const auto colon = line.find(": ");
    const auto colon_end = line.size() > 0 && line.back() == ':' ? line.size() - 1 : std::string::npos;
    const auto pos = colon != std::string::npos ? colon : colon_end;
    if (pos == std::string::npos) {
      fail(path, "malformed NRRD header line " + std::to_string(line_no) + ": \"" + line + "\"");
    }
    const std::string name = trim(line.substr(0, pos));
    const std::string key = toLower(name);
    // The format reads field names in any case; vtkNrrdReader 9.1 only in lower case, and a field
    // it misses ("dimensioN") left it reading through a null stream: refused, named.
    if (key != name)
      fail(path, "NRRD field \"" + name + "\" on line " + std::to_string(line_no) +
                     " is not in lower case (the VTK reader reads only lower-case field names)");
    const std::string value = pos + 1 < line.size() ? trim(line.substr(pos + 1)) : std::string();
    h.fields[key] = value;
    if (key == "data file" || key == "datafile") in_list = addDataFiles(h, path, value, kMaxLines);
  }
  if (!h.detached) {
    if (!ended) fail(path, "NRRD header never ends (no blank line) and names no \"data file\"");
    h.header_bytes = offset;
  }
  if (h.detached && h.data_files.empty()) fail(path, "\"data file\" lists no files");
  const fs::path folder = path.parent_path();
  for (auto& f : h.data_files) {
    if (f.is_relative()) f = folder / f;
    requireBesideHeader(path, f);  // "../../etc/passwd" or "/etc/shadow" are not voxels
  }
  return h;
}

/// Parses "(x,y,z)" vectors or "none"; returns one entry per axis.
std::vector<std::optional<Eigen::Vector3d>> parseVectors(const std::string& value,
                                                        const fs::path& path,
                                                        const std::string& field) {
  std::vector<std::optional<Eigen::Vector3d>> out;
  static const std::regex kItem(R"(\(([^)]*)\)|none)");
  for (auto it = std::sregex_iterator(value.begin(), value.end(), kItem);
       it != std::sregex_iterator(); ++it) {
    if ((*it)[0] == "none") {
      out.emplace_back(std::nullopt);
      continue;
    }
    std::string inner = (*it)[1];
    std::replace(inner.begin(), inner.end(), ',', ' ');
    const auto words = splitWords(inner);
    if (words.size() != 3) {
      fail(path, "\"" + field + "\" must hold 3-D vectors, got \"" + value + "\"");
    }
    Eigen::Vector3d v;
    for (int c = 0; c < 3; ++c) {
      const auto d = parseDouble(words[static_cast<std::size_t>(c)]);
      if (!d) fail(path, "\"" + field + "\" has a non-numeric value: \"" + value + "\"");
      v[c] = *d;
    }
    out.emplace_back(v);
  }
  return out;
}

/// The sign flip taking coordinates in a NRRD `space` into patient LPS (W)
/// (vh/io/patient_frames.h); identity for LPS and the non-anatomical spaces.
/// @throws LoadError naming `path` for a space that is not 3-D.
Eigen::Matrix3d lpsFromSpace(const std::string& space_in, const fs::path& path) {
  const std::string s = toLower(space_in);
  if (s.empty() || s == "left-posterior-superior" || s == "lps" || s == "scanner-xyz" ||
      s == "3d-right-handed" || s == "3d-left-handed") {
    return Eigen::Matrix3d::Identity();
  }
  if (s == "right-anterior-superior" || s == "ras") return lpsFromRasMatrix();
  if (s == "left-anterior-superior" || s == "las") return lpsFromLasMatrix();
  fail(path, "unsupported NRRD space \"" + space_in + "\" (only 3-D spaces are supported)");
}

std::string field(const NrrdHeader& h, const std::string& key) {
  const auto it = h.fields.find(key);
  return it == h.fields.end() ? std::string() : it->second;
}

void checkRawSizes(const NrrdHeader& h, const fs::path& path, std::uintmax_t total_bytes) {
  if (!h.detached) {
    const auto size = fileSize(path).value_or(0);
    const std::uintmax_t available = size > h.header_bytes ? size - h.header_bytes : 0;
    if (available < total_bytes) {
      fail(path, "truncated: expected " + std::to_string(total_bytes) +
                     " bytes of voxel data, found " + std::to_string(available));
    }
    return;
  }
  const std::uintmax_t n_files = h.data_files.size();
  if (total_bytes % n_files != 0) {
    fail(path, std::to_string(total_bytes) + " bytes of voxel data cannot be split evenly over " +
                   std::to_string(n_files) + " data files");
  }
  const std::uintmax_t per_file = total_bytes / n_files;
  for (const auto& f : h.data_files) {
    const auto size = fileSize(f);
    if (!size) fail(path, "data file " + f.string() + " is missing");
    if (*size < per_file) {
      fail(path, "truncated: data file " + f.filename().string() + " holds " +
                     std::to_string(*size) + " of the " + std::to_string(per_file) +
                     " bytes of voxel data expected");
    }
  }
}

/// Flips the rows (VTK's y axis) of every slice back, undoing vtkImageReader's FileLowerLeft-off
/// reading.
void flipRows(vtkImageData* image) {
  vtkDataArray* a = image->GetPointData()->GetScalars();
  int d[3];
  image->GetDimensions(d);
  const std::size_t row_bytes = static_cast<std::size_t>(d[0]) *
                                static_cast<std::size_t>(a->GetNumberOfComponents()) *
                                static_cast<std::size_t>(a->GetDataTypeSize());
  auto* bytes = static_cast<unsigned char*>(a->GetVoidPointer(0));
  std::vector<unsigned char> tmp(row_bytes);
  for (int k = 0; k < d[2]; ++k) {
    unsigned char* slice = bytes + static_cast<std::size_t>(k) * static_cast<std::size_t>(d[1]) * row_bytes;
    for (int j = 0; j < d[1] / 2; ++j) {
      unsigned char* r0 = slice + static_cast<std::size_t>(j) * row_bytes;
      unsigned char* r1 = slice + static_cast<std::size_t>(d[1] - 1 - j) * row_bytes;
      std::memcpy(tmp.data(), r0, row_bytes);
      std::memcpy(r0, r1, row_bytes);
      std::memcpy(r1, tmp.data(), row_bytes);
    }
  }
  a->Modified();
}

/// A one-component image of dims `sizes` over the same values (x fastest), for an image that
/// vtkNrrdReader read with the fastest axis as components.
vtkSmartPointer<vtkImageData> asScalarVolume(vtkImageData* image, const std::array<int, 3>& sizes) {
  vtkDataArray* a = image->GetPointData()->GetScalars();
  vtkSmartPointer<vtkDataArray> scalars;
  scalars.TakeReference(vtkDataArray::CreateDataArray(a->GetDataType()));
  scalars->SetNumberOfComponents(1);
  scalars->SetNumberOfTuples(a->GetNumberOfTuples() * a->GetNumberOfComponents());
  std::memcpy(scalars->GetVoidPointer(0), a->GetVoidPointer(0),
              static_cast<std::size_t>(scalars->GetNumberOfTuples()) *
                  static_cast<std::size_t>(a->GetDataTypeSize()));
  auto out = vtkSmartPointer<vtkImageData>::New();
  out->SetDimensions(sizes[0], sizes[1], sizes[2]);
  out->GetPointData()->SetScalars(scalars);
  return out;
}

/// Layer `layer` of a layered NRRD's `layer_count` interleaved layers (the list axis fastest),
/// decoded from the raw or gzip data (zlib), as a one-component image of dims `sizes`.
vtkSmartPointer<vtkImageData> readLayer(const NrrdHeader& h, const fs::path& path, bool gzip, int vtk_type,
                                        std::size_t type_size, int layer_count, int layer,
                                        const std::array<int, 3>& sizes) {
  const std::size_t voxels = static_cast<std::size_t>(sizes[0]) * static_cast<std::size_t>(sizes[1]) *
                             static_cast<std::size_t>(sizes[2]);
  const std::size_t total = voxels * static_cast<std::size_t>(layer_count) * type_size;
  const fs::path data = h.detached ? h.data_files.front() : path;
  const std::uintmax_t offset = h.detached ? 0 : h.header_bytes;
  std::ifstream in(data, std::ios::binary);
  if (!in) fail(path, "cannot open the voxel data " + data.string());
  in.seekg(static_cast<std::streamoff>(offset));
  std::vector<unsigned char> bytes;
  if (!gzip) {
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(data, ec);
    if (ec || size < offset || size - offset < total) fail(path, "truncated layered voxel data");
    bytes.resize(total);
    in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(total));
    if (static_cast<std::size_t>(in.gcount()) != total) fail(path, "truncated layered voxel data");
  } else {
    std::vector<unsigned char> packed((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // Deflate expands at most 1032:1; a header announcing more than that is a damaged file.
    if (total / 1032 > packed.size() + 64) fail(path, "truncated gzip voxel data (far less data than the header announces)");
    bytes.resize(total);
    z_stream z{};
    if (inflateInit2(&z, 16 + MAX_WBITS) != Z_OK) fail(path, "zlib could not start");
    z.next_in = packed.data();
    z.avail_in = static_cast<uInt>(std::min<std::size_t>(packed.size(), std::numeric_limits<uInt>::max()));
    z.next_out = bytes.data();
    z.avail_out = static_cast<uInt>(std::min<std::size_t>(total, std::numeric_limits<uInt>::max()));
    const int rc = inflate(&z, Z_FINISH);
    const std::size_t produced = total - z.avail_out;
    inflateEnd(&z);
    if ((rc != Z_STREAM_END && rc != Z_OK && rc != Z_BUF_ERROR) || produced != total) {
      fail(path, "corrupt or truncated gzip voxel data (" + std::to_string(produced) + " of " + std::to_string(total) +
                     " bytes)");
    }
  }
  const std::string endian = toLower(field(h, "endian"));
  const bool swap = type_size > 1 && ((endian == "big") != (std::endian::native == std::endian::big)) && !endian.empty();
  vtkSmartPointer<vtkDataArray> scalars;
  scalars.TakeReference(vtkDataArray::CreateDataArray(vtk_type));
  scalars->SetNumberOfComponents(1);
  scalars->SetNumberOfTuples(static_cast<vtkIdType>(voxels));
  auto* to = static_cast<unsigned char*>(scalars->GetVoidPointer(0));
  const std::size_t stride = type_size * static_cast<std::size_t>(layer_count);
  for (std::size_t v = 0; v < voxels; ++v) {
    unsigned char* dst = to + v * type_size;
    std::memcpy(dst, bytes.data() + v * stride + static_cast<std::size_t>(layer) * type_size, type_size);
    if (swap) std::reverse(dst, dst + type_size);
  }
  auto out = vtkSmartPointer<vtkImageData>::New();
  out->SetDimensions(sizes[0], sizes[1], sizes[2]);
  out->GetPointData()->SetScalars(scalars);
  return out;
}

/// Reads raw or gzip voxels with vtkNrrdReader and undoes its quirks (row flip, components).
vtkSmartPointer<vtkImageData> readWithVtk(const NrrdHeader& h, const fs::path& path, bool gzip,
                                          const std::string& type, std::size_t type_size,
                                          std::uintmax_t voxel_count,
                                          const std::array<int, 3>& sizes) {
  const bool raw = !gzip;
  VtkErrorCapture capture;
  auto reader = vtkSmartPointer<vtkNrrdReader>::New();
  capture.watch(reader);
  reader->SetFileName(path.string().c_str());
  reader->Update();
  if (capture.hasErrors()) {
    const std::string what = gzip ? "corrupt or truncated gzip voxel data" : "voxel data could not be read";
    fail(path, what + " (" + capture.firstError() + ")");
  }
  vtkSmartPointer<vtkImageData> out = reader->GetOutput();
  vtkDataArray* scalars = out != nullptr ? out->GetPointData()->GetScalars() : nullptr;
  if (scalars == nullptr || static_cast<std::uintmax_t>(scalars->GetNumberOfValues()) != voxel_count) {
    fail(path, "no voxel data was read, or not the " + std::to_string(voxel_count) +
                   " values the header announces");
  }
  if (static_cast<std::size_t>(scalars->GetDataTypeSize()) != type_size) {
    fail(path, std::string("VTK read ") + scalars->GetDataTypeAsString() +
                   " voxels where the header says \"" + type + "\"");
  }
  const std::string space_value = field(h, "space");
  if (raw && (space_value == "left-anterior-superior" || space_value == "LAS" ||
              space_value == "3D-left-handed")) {
    flipRows(out);
  }
  if (scalars->GetNumberOfComponents() != 1) out = asScalarVolume(out, sizes);

  return out;
}

/// What the header says about the values, checked: their count, type and encoding, and the
/// grid. For a layered NRRD the list axis is taken off `size_words` and `kinds`.
struct NrrdLayout {
  bool layered = false;  ///< 4-D with a leading "list" axis: a stack of 3-D layers.
  int layer_count = 1;
  std::vector<std::string> size_words;  ///< The 3 spatial sizes as written.
  std::vector<std::string> kinds;       ///< The 3 spatial axes' kinds (lower case), if given.
  std::array<int, 3> sizes{};           ///< The grid [voxels].
  std::uintmax_t voxel_count = 0;       ///< Voxels of one layer.
  std::uintmax_t value_count = 0;       ///< Values in the file (all layers).
  std::string type;                     ///< The "type" as written.
  NrrdType value_type;
  bool raw = false, gzip = false, text = false;  ///< The encoding.
};

/// "dimension", "kinds" and "sizes": a 3-D volume or a 4-D layered one with `layer` in it.
/// @throws LoadError naming `path` otherwise, or for absurd sizes.
void checkDimensions(const NrrdHeader& h, const fs::path& path, int layer, NrrdLayout& l) {
  const auto dimension = parseInt(field(h, "dimension"));
  if (!dimension) fail(path, "NRRD header has no valid \"dimension\"");
  // A 4-D NRRD whose first (fastest) axis is a list is a stack of 3-D layers: 3D Slicer's
  // segmentation with overlapping segments (.seg.nrrd, "kinds: list domain domain domain").
  l.kinds = splitWords(toLower(field(h, "kinds")));
  l.layered = *dimension == 4 && !l.kinds.empty() && l.kinds[0] == "list";
  if (*dimension != 3 && !l.layered) {
    fail(path, "is a " + std::to_string(*dimension) +
                   "-D NRRD; only 3-D scalar volumes (and 4-D layered segmentations whose first "
                   "axis is a \"list\") are supported");
  }
  l.size_words = splitWords(field(h, "sizes"));
  if (l.size_words.size() != static_cast<std::size_t>(*dimension)) {
    fail(path, "NRRD \"sizes\" must list " + std::to_string(*dimension) + " sizes");
  }
  if (l.layered) {
    const auto n = parseInt(l.size_words[0]);
    if (!n || *n <= 0 || *n > 256) fail(path, "NRRD \"sizes\" has an invalid layer count \"" + l.size_words[0] + "\"");
    l.layer_count = static_cast<int>(*n);
    l.size_words.erase(l.size_words.begin());
    l.kinds.erase(l.kinds.begin());
  }
  if (layer < 0 || layer >= l.layer_count) {
    fail(path, "has " + std::to_string(l.layer_count) + " layer(s); layer " + std::to_string(layer) +
                   " was asked for");
  }
  std::uintmax_t voxel_count = 1;
  for (const auto& w : l.size_words) {
    const auto v = parseInt(w);
    if (!v || *v <= 0) fail(path, "NRRD \"sizes\" has an invalid size \"" + w + "\"");
    if (*v > (1 << 20) || voxel_count > (std::uintmax_t{1} << 40)) fail(path, "NRRD \"sizes\" announce an absurd number of values");
    voxel_count *= static_cast<std::uintmax_t>(*v);
  }
  if (voxel_count > (std::uintmax_t{1} << 40) / static_cast<std::uintmax_t>(l.layer_count)) {
    fail(path, "NRRD \"sizes\" announce an absurd number of values");
  }
  l.voxel_count = voxel_count;
  l.value_count = voxel_count * static_cast<std::uintmax_t>(l.layer_count);
}

/// "type", "encoding", line / byte skips and the spatial axes' kinds.
/// @throws LoadError naming `path` for what is not supported.
void checkValues(const NrrdHeader& h, const fs::path& path, NrrdLayout& l) {
  l.type = field(h, "type");
  if (l.type.empty()) fail(path, "NRRD header has no \"type\"");
  l.value_type = nrrdType(l.type);
  if (l.value_type.size == 0) fail(path, "unsupported NRRD type \"" + l.type + "\"");
  const std::string encoding = toLower(field(h, "encoding"));
  l.raw = encoding == "raw";
  l.gzip = encoding == "gzip" || encoding == "gz";
  l.text = encoding == "ascii" || encoding == "text" || encoding == "txt";
  if (!l.raw && !l.gzip && !l.text) {
    fail(path, "unsupported NRRD encoding \"" + field(h, "encoding") +
                   "\" (raw, gzip and ascii are supported)");
  }
  for (const char* key : {"line skip", "lineskip", "byte skip", "byteskip"}) {
    if (parseInt(field(h, key)).value_or(0) != 0) {
      fail(path, std::string("NRRD \"") + key + "\" is not supported (by vtkNrrdReader)");
    }
  }
  for (std::size_t a = 0; a < l.kinds.size(); ++a) {
    if (l.kinds[a] != "domain" && l.kinds[a] != "space" && l.kinds[a] != "???" && l.kinds[a] != "none") {
      fail(path, "axis " + std::to_string(a) + " has kind \"" + l.kinds[a] +
                     "\"; only scalar volumes (3 spatial axes) are supported");
    }
  }
}

/// The data files: ranges and file lists vtkNrrdReader can read, present, long enough (raw) and
/// starting with a gzip header (gzip).
/// @throws LoadError naming `path` otherwise.
void checkDataFiles(const NrrdHeader& h, const fs::path& path, const NrrdLayout& l) {
  const std::string data_file = field(h, "data file").empty() ? field(h, "datafile") : field(h, "data file");
  if (const auto words = splitWords(data_file); words.size() >= 4 &&
                                                              words[0].find('%') != std::string::npos) {
    if (parseInt(words[3]).value_or(1) < 0) {
      fail(path, "descending \"data file\" ranges (negative step) are not supported by "
                 "vtkNrrdReader; list the files with \"data file: LIST\" instead");
    }
  }
  if (h.data_files.size() > 1 && !l.text) {
    // vtkNrrdReader reads file lists as one 2-D slice per file only, and crashes on file lists
    // of volumes whose fastest axis it takes for vector components (<= 9 voxels).
    if (l.gzip) fail(path, "gzip data split over several files is not supported by vtkNrrdReader");
    const auto nz = parseInt(l.size_words[2]).value_or(0);
    const auto nx = parseInt(l.size_words[0]).value_or(0);
    if (static_cast<long long>(h.data_files.size()) != nz) {
      fail(path, "data split over " + std::to_string(h.data_files.size()) + " files for " +
                     std::to_string(nz) + " slices; vtkNrrdReader needs one 2-D slice per file");
    }
    if (nx <= 9) {
      fail(path, "slice files of volumes 9 voxels wide or less are not supported by "
                 "vtkNrrdReader (it reads the fastest axis as vector components)");
    }
  }
  for (const auto& f : h.data_files) requireRegularFile(f, path);  // also: no FIFO or device
  if (l.raw) checkRawSizes(h, path, l.value_count * l.value_type.size);
  if (l.gzip) {
    const fs::path data = h.detached ? h.data_files.front() : path;
    if (!startsWithGzipMagic(data, h.detached ? 0 : h.header_bytes)) {
      fail(path, "corrupt gzip voxel data: " + (h.detached ? data.filename().string() : std::string("the data")) +
                     " does not start with a gzip header");
    }
  }
}

/// The header read and checked for a load of `layer`.
/// @throws LoadError naming `path` for what cannot be read.
NrrdLayout checkedLayout(const NrrdHeader& h, const fs::path& path, int layer) {
  NrrdLayout l;
  checkDimensions(h, path, layer, l);
  checkValues(h, path, l);
  requireDeclaredFits(path, static_cast<std::uint64_t>(l.value_count) * l.value_type.size);
  checkDataFiles(h, path, l);
  for (int a = 0; a < 3; ++a) {
    l.sizes[static_cast<std::size_t>(a)] = static_cast<int>(*parseInt(l.size_words[static_cast<std::size_t>(a)]));
  }
  return l;
}

/// The voxels (layer `layer` of a layered NRRD): through VTK, except ascii and layers.
vtkSmartPointer<vtkImageData> readVoxels(const NrrdHeader& h, const fs::path& path, const NrrdLayout& l, int layer) {
  if (l.layered) {
    // vtkNrrdReader 9.1 reads only the first three sizes of a 4-D NRRD: the layers are decoded
    // here (raw, or gzip through zlib) and the chosen one is extracted.
    if (l.text) fail(path, "ascii-encoded layered NRRD is not supported");
    if (h.data_files.size() > 1) fail(path, "a layered NRRD split over several data files is not supported");
    return readLayer(h, path, l.gzip, l.value_type.vtk_type, l.value_type.size, l.layer_count, layer, l.sizes);
  }
  if (l.text) return readAscii(h, path, l.value_type.vtk_type, l.sizes, l.voxel_count);
  return readWithVtk(h, path, l.gzip, l.type, l.value_type.size, l.voxel_count, l.sizes);
}

/// The grid axes in the NRRD space (columns: axis i, j, k scaled by the spacing, in the space's
/// length unit): "space directions", else the diagonal of "spacings" (1 where absent).
/// @throws LoadError naming `path` for a spacing that is not a positive number (0, nan,
///         negative: a grid the file does not describe).
/// @throws LoadError naming `path` for malformed or non-spatial directions.
Eigen::Matrix3d gridAxes(const NrrdHeader& h, const fs::path& path, bool layered) {
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  const std::string directions = field(h, "space directions");
  if (!directions.empty()) {
    auto vectors = parseVectors(directions, path, "space directions");
    if (layered && !vectors.empty()) {
      if (vectors.front()) fail(path, "the list axis of a layered NRRD must be \"none\" in \"space directions\"");
      vectors.erase(vectors.begin());
    }
    if (vectors.size() != 3) fail(path, "\"space directions\" must give 3 vectors");
    for (int c = 0; c < 3; ++c) {
      if (!vectors[static_cast<std::size_t>(c)]) {
        fail(path, "axis " + std::to_string(c) +
                       " is not spatial (\"none\" in space directions); only scalar volumes "
                       "are supported");
      }
      axes.col(c) = *vectors[static_cast<std::size_t>(c)];
    }
    return axes;
  }
  auto words = splitWords(field(h, "spacings"));
  if (layered && !words.empty()) words.erase(words.begin());  // the list axis ("nan")
  for (int c = 0; c < 3; ++c) {
    double s = 1.0;
    if (static_cast<std::size_t>(c) < words.size()) {
      const auto d = parseDouble(words[static_cast<std::size_t>(c)]);
      if (!d || !(*d > 0.0)) {
        fail(path, "\"spacings\" must be positive numbers, found \"" + field(h, "spacings") + "\"");
      }
      s = *d;
    }
    axes(c, c) = s;
  }
  return axes;
}

/// "space origin" in the NRRD space (its length unit); zero when absent.
/// @throws LoadError naming `path` when malformed.
Eigen::Vector3d spaceOrigin(const NrrdHeader& h, const fs::path& path) {
  const std::string o = field(h, "space origin");
  if (o.empty()) return Eigen::Vector3d::Zero();
  const auto vectors = parseVectors(o, path, "space origin");
  if (vectors.size() != 1 || !vectors[0]) fail(path, "invalid \"space origin\": \"" + o + "\"");
  return *vectors[0];
}

/// Metres per length unit of the space: "space units" (quoted, one per space axis) or "units";
/// none means millimetres.
/// @throws LoadError naming `path` for an unknown unit or axes in different units.
double lengthUnitToM(const NrrdHeader& h, const fs::path& path) {
  std::string units = field(h, "space units");
  if (units.empty()) units = field(h, "units");
  double to_m = 1e-3;
  static const std::regex kQuoted(R"re("([^"]*)")re");
  bool first = true;
  for (auto it = std::sregex_iterator(units.begin(), units.end(), kQuoted); it != std::sregex_iterator(); ++it) {
    const std::string u = (*it)[1];
    const auto factor = lengthUnitToMetres(u);
    if (!factor) fail(path, "unsupported length unit \"" + u + "\" in the NRRD header");
    if (!first && *factor != to_m) fail(path, "NRRD axes have different length units");
    to_m = *factor;
    first = false;
  }
  return to_m;
}

}  // namespace

std::map<std::string, std::string> readNrrdKeyValues(const fs::path& path) { return readHeader(path).key_values; }

LoadedVolume loadNrrd(const fs::path& path, int layer) {
  const NrrdHeader h = readHeader(path);
  const NrrdLayout layout = checkedLayout(h, path, layer);
  vtkSmartPointer<vtkImageData> out = readVoxels(h, path, layout, layer);

  // --- geometry in W (patient LPS) [m] ---
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();
  splitAxes(gridAxes(h, path, layout.layered), path, direction, spacing);
  const Eigen::Vector3d origin = spaceOrigin(h, path);
  const Eigen::Matrix3d lps_from_space = lpsFromSpace(field(h, "space"), path);
  const double to_m = lengthUnitToM(h, path);

  RawVolume raw_volume;
  raw_volume.image = out;
  raw_volume.geometry.spacing_m = spacing * to_m;
  raw_volume.geometry.direction_W = lps_from_space * direction;
  raw_volume.geometry.origin_W_m = lps_from_space * origin * to_m;
  raw_volume.info.format = "NRRD";
  const std::string content = field(h, "content");
  raw_volume.info.description = content.empty() ? path.filename().string() : content;
  if (layout.layered) {
    raw_volume.info.notices.push_back("layer " + std::to_string(layer + 1) + " of " +
                                      std::to_string(layout.layer_count) + " of a layered segmentation");
  }
  return finishVolume(std::move(raw_volume), path);
}

}  // namespace vh::io::detail
