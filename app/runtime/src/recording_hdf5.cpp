/// @file
/// HDF5 recordings (recording_hdf5.h): the HDF5 library's C API (Debian's libhdf5, thread-safe
/// build) behind a few small owners of its handles.

#include "vh/runtime/recording_hdf5.h"
#include "vh/runtime/tick_columns.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <hdf5.h>
#include <nlohmann/json.hpp>

#include "vh/io/available_memory.h"
#include "vh/io/private_files.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metadata.h"
#include "recording_internal.h"

namespace vh::runtime {
namespace {

constexpr const char* kFormatName = "VolumeHaptics recording";
constexpr hsize_t kChunkRows = 16384;  // rows per compressed chunk of a column
constexpr unsigned kDeflateLevel = 4;

/// Owns one HDF5 identifier and closes it with `Close` (H5Fclose, H5Dclose, ...).
template <herr_t (*Close)(hid_t)>
class Handle {
 public:
  Handle() = default;
  explicit Handle(hid_t id) : id_(id) {}
  ~Handle() {
    if (id_ >= 0) Close(id_);
  }
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, -1)) {}
  Handle& operator=(Handle&& other) noexcept {
    std::swap(id_, other.id_);
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  hid_t get() const noexcept { return id_; }
  hid_t release() noexcept { return std::exchange(id_, -1); }
  bool valid() const noexcept { return id_ >= 0; }

 private:
  hid_t id_ = -1;
};
using File = Handle<H5Fclose>;
using Group = Handle<H5Gclose>;
using Dataset = Handle<H5Dclose>;
using Dataspace = Handle<H5Sclose>;
using Datatype = Handle<H5Tclose>;
using Attribute = Handle<H5Aclose>;
using PropertyList = Handle<H5Pclose>;

/// HDF5 prints its error stack to stderr by default; the messages here say what failed instead.
void silenceHdf5() {
  static const bool silenced = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)silenced;
}

/// A column kind's HDF5 types (in the file, little-endian; in memory, native) and size [bytes].
struct KindTypes {
  hid_t file;
  hid_t memory;
  std::size_t size;
};
KindTypes typesOf(TickColumn::Kind kind) {
  switch (kind) {
    case TickColumn::kU64: return {H5T_STD_U64LE, H5T_NATIVE_UINT64, 8};
    case TickColumn::kU32: return {H5T_STD_U32LE, H5T_NATIVE_UINT32, 4};
    case TickColumn::kI32: return {H5T_STD_I32LE, H5T_NATIVE_INT32, 4};
    case TickColumn::kI64: return {H5T_STD_I64LE, H5T_NATIVE_INT64, 8};
    case TickColumn::kF64: break;
  }
  return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 8};
}

/// The variable-length UTF-8 string type, its creation checked by `c` (a Writer or a Reader).
template <typename Checker>
Datatype utf8String(const Checker& c, const std::string& what) {
  Datatype t(c.check(H5Tcopy(H5T_C_S1), what));
  c.check(H5Tset_size(t.get(), H5T_VARIABLE), what);
  c.check(H5Tset_cset(t.get(), H5T_CSET_UTF8), what);
  return t;
}

// ---- Writing ------------------------------------------------------------------------------------

/// Throws "cannot write TARGET: <what>" when `status` is an HDF5 failure (negative).
struct Writer {
  std::string target;
  hid_t check(hid_t status, const std::string& what) const {
    if (status < 0) throw std::runtime_error("cannot write " + target + ": HDF5 failed to write " + what);
    return status;
  }
};

void writeStringAttribute(const Writer& w, hid_t object, const char* name, const std::string& value) {
  Datatype type = utf8String(w, name);
  Dataspace space(w.check(H5Screate(H5S_SCALAR), name));
  Attribute a(w.check(H5Acreate2(object, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), name));
  const char* text = value.c_str();
  w.check(H5Awrite(a.get(), type.get(), &text), name);
}

template <typename T>
void writeNumberAttribute(const Writer& w, hid_t object, const char* name, hid_t file_type, hid_t memory_type,
                          T value) {
  Dataspace space(w.check(H5Screate(H5S_SCALAR), name));
  Attribute a(w.check(H5Acreate2(object, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), name));
  w.check(H5Awrite(a.get(), memory_type, &value), name);
}

/// A scalar string dataset (the metadata JSON: too long for an attribute's 64 KiB).
void writeStringScalar(const Writer& w, hid_t parent, const char* name, const std::string& value) {
  Datatype type = utf8String(w, name);
  Dataspace space(w.check(H5Screate(H5S_SCALAR), name));
  Dataset d(w.check(H5Dcreate2(parent, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), name));
  const char* text = value.c_str();
  w.check(H5Dwrite(d.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, &text), name);
}

/// Voxels per compressed chunk of a volume, and per slab written at a time [voxels].
constexpr hsize_t kVolumeChunkVoxels = hsize_t{1} << 16;

/// The i rows of one chunk (and slab) of a (nx, ny, nz) volume: whole (j, k) planes, about
/// kVolumeChunkVoxels voxels, at least one plane.
hsize_t volumeSlabRows(const std::vector<hsize_t>& dims) {
  return std::max<hsize_t>(1, std::min<hsize_t>(dims[0], kVolumeChunkVoxels / (dims[1] * dims[2])));
}

/// A dataset creation list for `dims`: chunked (kChunkRows rows of a column; volumeSlabRows()
/// planes of a volume), shuffled and compressed; an empty dataset stays contiguous (HDF5 cannot
/// chunk one with fixed dimensions).
PropertyList compressed(const Writer& w, const std::vector<hsize_t>& dims, const std::string& what) {
  PropertyList p(w.check(H5Pcreate(H5P_DATASET_CREATE), what));
  for (hsize_t d : dims)
    if (d == 0) return p;
  std::vector<hsize_t> chunk = dims;
  if (dims.size() == 1) {
    chunk[0] = std::min(dims[0], kChunkRows);
  } else {
    chunk[0] = volumeSlabRows(dims);
  }
  w.check(H5Pset_chunk(p.get(), static_cast<int>(chunk.size()), chunk.data()), what);
  w.check(H5Pset_shuffle(p.get()), what);
  w.check(H5Pset_deflate(p.get(), kDeflateLevel), what);
  return p;
}

/// A link creation list that keeps the order of creation, so h5py lists datasets in the order
/// written (the --csv columns' order) rather than by name.
PropertyList creationOrdered(const Writer& w, hid_t list_class) {
  PropertyList p(w.check(H5Pcreate(list_class), "a property list"));
  w.check(H5Pset_link_creation_order(p.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), "a property list");
  return p;
}

Group createGroup(const Writer& w, hid_t parent, const char* name) {
  PropertyList order = creationOrdered(w, H5P_GROUP_CREATE);
  return Group(w.check(H5Gcreate2(parent, name, H5P_DEFAULT, order.get(), H5P_DEFAULT), name));
}

Dataset createDataset(const Writer& w, hid_t parent, const std::string& name, hid_t file_type,
                      const std::vector<hsize_t>& dims) {
  Dataspace space(w.check(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), name));
  PropertyList create = compressed(w, dims, name);
  return Dataset(w.check(
      H5Dcreate2(parent, name.c_str(), file_type, space.get(), H5P_DEFAULT, create.get(), H5P_DEFAULT), name));
}

void writeStrings(const Writer& w, hid_t parent, const char* name, const std::vector<std::string>& values) {
  Datatype type = utf8String(w, name);
  const hsize_t n = values.size();
  Dataspace space(w.check(H5Screate_simple(1, &n, nullptr), name));
  PropertyList create = compressed(w, {n}, name);
  Dataset d(w.check(H5Dcreate2(parent, name, type.get(), space.get(), H5P_DEFAULT, create.get(), H5P_DEFAULT), name));
  if (n == 0) return;
  std::vector<const char*> text;
  text.reserve(values.size());
  for (const std::string& v : values) text.push_back(v.c_str());
  w.check(H5Dwrite(d.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, text.data()), name);
}

template <typename T>
void writeNumbers(const Writer& w, hid_t parent, const char* name, hid_t file_type, hid_t memory_type,
                  const std::vector<T>& values, const char* unit) {
  Dataset d = createDataset(w, parent, name, file_type, {values.size()});
  if (!values.empty()) w.check(H5Dwrite(d.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), name);
  writeStringAttribute(w, d.get(), "unit", unit);
}

void writeTicks(const Writer& w, hid_t file, const std::vector<TickRecord>& records) {
  Group ticks = createGroup(w, file, "ticks");
  std::vector<unsigned char> column(records.size() * 8);
  for (const TickColumn& c : tickColumns()) {
    const KindTypes types = typesOf(c.kind);
    for (std::size_t r = 0; r < records.size(); ++r)
      std::memcpy(column.data() + r * types.size, reinterpret_cast<const unsigned char*>(&records[r]) + c.offset,
                  types.size);
    Dataset d = createDataset(w, ticks.get(), c.name, types.file, {records.size()});
    if (!records.empty())
      w.check(H5Dwrite(d.get(), types.memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, column.data()),
              std::string("/ticks/") + c.name);
    writeStringAttribute(w, d.get(), "unit", c.unit);
    writeStringAttribute(w, d.get(), "description", c.description);
  }
}

void writeEvents(const Writer& w, hid_t file, const std::vector<RecordingEvent>& events) {
  std::vector<double> t_s;
  std::vector<std::uint64_t> tick;
  std::vector<std::string> type, detail;
  std::vector<double> marker_t_s;
  std::vector<std::uint64_t> marker_tick;
  std::vector<std::string> marker_label;
  for (const RecordingEvent& e : events) {
    t_s.push_back(e.time_s);
    tick.push_back(e.tick);
    type.push_back(e.type);
    detail.push_back(e.detail_json);
    if (e.type != "marker") continue;
    marker_t_s.push_back(e.time_s);
    marker_tick.push_back(e.tick);
    const nlohmann::json d = jsonNestingDepth(e.detail_json) <= kMaxRecordingJsonDepth
                                 ? nlohmann::json::parse(e.detail_json, nullptr, /*allow_exceptions=*/false)
                                 : nlohmann::json();
    marker_label.push_back(d.is_object() && d.contains("label") && d["label"].is_string()
                               ? d["label"].get<std::string>() : std::string());
  }
  Group g = createGroup(w, file, "events");
  writeNumbers(w, g.get(), "t_s", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, t_s, "s");
  writeNumbers(w, g.get(), "tick", H5T_STD_U64LE, H5T_NATIVE_UINT64, tick, "1");
  writeStrings(w, g.get(), "type", type);
  writeStrings(w, g.get(), "detail_json", detail);
  Group m = createGroup(w, file, "markers");
  writeNumbers(w, m.get(), "t_s", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, marker_t_s, "s");
  writeNumbers(w, m.get(), "tick", H5T_STD_U64LE, H5T_NATIVE_UINT64, marker_tick, "1");
  writeStrings(w, m.get(), "label", marker_label);
}

/// The volume as a (nx, ny, nz) dataset in C order (k fastest), so that h5py's array is [i, j, k].
void writeVolume(const Writer& w, hid_t group, const char* name, const haptics::ScalarVolume& volume,
                 double isovalue) {
  const auto& g = volume.geometry();
  const std::vector<hsize_t> dims = {static_cast<hsize_t>(g.dims[0]), static_cast<hsize_t>(g.dims[1]),
                                     static_cast<hsize_t>(g.dims[2])};
  // float32 when every value is exact in it (CT in HU, 8- and 16-bit data): a first pass.
  bool exact_in_float = true;
  for (int k = 0; k < g.dims[2] && exact_in_float; ++k)
    for (int j = 0; j < g.dims[1] && exact_in_float; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double v = volume.voxel(i, j, k);
        if (static_cast<double>(static_cast<float>(v)) != v) {
          exact_in_float = false;
          break;
        }
      }
  const std::string where = std::string("/volume/") + name;
  Dataset d = createDataset(w, group, name, exact_in_float ? H5T_IEEE_F32LE : H5T_IEEE_F64LE, dims);
  // Written a slab of whole (j, k) planes at a time (one chunk each), k fastest: the memory
  // held is one slab, not a copy of the volume (a 512^3 CT would take 1 GiB as doubles).
  const hsize_t rows = volumeSlabRows(dims);
  std::vector<double> slab(static_cast<std::size_t>(rows * dims[1] * dims[2]));
  Dataspace file_space(w.check(H5Dget_space(d.get()), where));
  for (hsize_t i0 = 0; i0 < dims[0]; i0 += rows) {
    const hsize_t count[3] = {std::min(rows, dims[0] - i0), dims[1], dims[2]};
    const hsize_t start[3] = {i0, 0, 0};
    std::size_t n = 0;
    for (hsize_t i = i0; i < i0 + count[0]; ++i)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int k = 0; k < g.dims[2]; ++k) slab[n++] = volume.voxel(static_cast<int>(i), j, k);
    w.check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), where);
    Dataspace memory_space(w.check(H5Screate_simple(3, count, nullptr), where));
    w.check(H5Dwrite(d.get(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(), H5P_DEFAULT, slab.data()),
            where);
  }
  // Row-major, as HDF5 stores a 4 x 4 array.
  const Eigen::Matrix<double, 4, 4, Eigen::RowMajor> affine = g.indexToWorld();
  const hsize_t shape[2] = {4, 4};
  Dataspace space(w.check(H5Screate_simple(2, shape, nullptr), where));
  Attribute a(w.check(H5Acreate2(d.get(), "affine_LPS_m", H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                      where));
  w.check(H5Awrite(a.get(), H5T_NATIVE_DOUBLE, affine.data()), where);
  writeNumberAttribute(w, d.get(), "isovalue", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, isovalue);
  writeStringAttribute(w, d.get(), "unit", "data units");
  writeStringAttribute(w, d.get(), "index_order", "i, j, k (h5py / NumPy); k, j, i in MATLAB");
}

// ---- Reading ------------------------------------------------------------------------------------

struct Reader {
  std::string where;  // "FILE: "
  hid_t check(hid_t status, const std::string& what) const {
    if (status < 0) throw std::runtime_error(where + "cannot read " + what + " (damaged or not written by this program)");
    return status;
  }
};

bool hasLink(hid_t parent, const char* name) { return H5Lexists(parent, name, H5P_DEFAULT) > 0; }

std::string readStringAttribute(const Reader& r, hid_t object, const char* name) {
  if (H5Aexists(object, name) <= 0) throw std::runtime_error(r.where + "no attribute " + name);
  Attribute a(r.check(H5Aopen(object, name, H5P_DEFAULT), name));
  Datatype stored(r.check(H5Aget_type(a.get()), name));
  if (H5Tget_class(stored.get()) != H5T_STRING || H5Tis_variable_str(stored.get()) <= 0)
    throw std::runtime_error(r.where + "attribute " + name + " is not a string");
  Datatype type = utf8String(r, name);
  char* text = nullptr;
  r.check(H5Aread(a.get(), type.get(), &text), name);
  std::string value = text != nullptr ? text : "";
  H5free_memory(text);
  return value;
}

template <typename T>
T readNumberAttribute(const Reader& r, hid_t object, const char* name, hid_t memory_type) {
  if (H5Aexists(object, name) <= 0) throw std::runtime_error(r.where + "no attribute " + name);
  Attribute a(r.check(H5Aopen(object, name, H5P_DEFAULT), name));
  Dataspace space(r.check(H5Aget_space(a.get()), name));
  if (H5Sget_simple_extent_npoints(space.get()) != 1)
    throw std::runtime_error(r.where + "attribute " + name + " is not one number");
  Datatype stored(r.check(H5Aget_type(a.get()), name));
  if (H5Tget_class(stored.get()) != H5T_INTEGER && H5Tget_class(stored.get()) != H5T_FLOAT)
    throw std::runtime_error(r.where + "attribute " + name + " is not a number");
  T value{};
  r.check(H5Aread(a.get(), memory_type, &value), name);
  return value;
}

/// The length of 1-D dataset `name` under `parent` whose type is of `type_class`.
hsize_t rowsOf(const Reader& r, hid_t dataset, const std::string& name, H5T_class_t type_class) {
  Dataspace space(r.check(H5Dget_space(dataset), name));
  hsize_t n = 0;
  if (H5Sget_simple_extent_ndims(space.get()) != 1 || H5Sget_simple_extent_dims(space.get(), &n, nullptr) < 0)
    throw std::runtime_error(r.where + name + " is not a one-dimensional dataset");
  Datatype stored(r.check(H5Dget_type(dataset), name));
  if (H5Tget_class(stored.get()) != type_class)
    throw std::runtime_error(r.where + name + (type_class == H5T_STRING ? " is not strings" : " is not numbers"));
  if (type_class == H5T_STRING && H5Tis_variable_str(stored.get()) <= 0)
    throw std::runtime_error(r.where + name + " is not variable-length strings");
  return n;
}

std::vector<std::string> readStrings(const Reader& r, hid_t parent, const std::string& group, const char* name) {
  const std::string where = group + "/" + name;
  if (!hasLink(parent, name)) throw std::runtime_error(r.where + "no dataset " + where);
  Dataset d(r.check(H5Dopen2(parent, name, H5P_DEFAULT), where));
  const hsize_t n = rowsOf(r, d.get(), where, H5T_STRING);
  io::requireFitsInMemory(n * sizeof(char*), r.where + where);
  Datatype type = utf8String(r, where);
  std::vector<char*> text(static_cast<std::size_t>(n), nullptr);
  std::vector<std::string> out;
  if (n == 0) return out;
  r.check(H5Dread(d.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, text.data()), where);
  out.reserve(text.size());
  for (char* t : text) out.emplace_back(t != nullptr ? t : "");
  Dataspace space(H5Dget_space(d.get()));
  H5Dvlen_reclaim(type.get(), space.get(), H5P_DEFAULT, text.data());
  return out;
}

std::string readStringScalar(const Reader& r, hid_t parent, const char* name) {
  if (!hasLink(parent, name)) throw std::runtime_error(r.where + "no dataset /" + name);
  Dataset d(r.check(H5Dopen2(parent, name, H5P_DEFAULT), name));
  Dataspace space(r.check(H5Dget_space(d.get()), name));
  Datatype stored(r.check(H5Dget_type(d.get()), name));
  if (H5Sget_simple_extent_type(space.get()) != H5S_SCALAR || H5Tget_class(stored.get()) != H5T_STRING ||
      H5Tis_variable_str(stored.get()) <= 0)
    throw std::runtime_error(r.where + "/" + name + " is not one string");
  Datatype type = utf8String(r, name);
  char* text = nullptr;
  r.check(H5Dread(d.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, &text), name);
  std::string value = text != nullptr ? text : "";
  H5free_memory(text);
  return value;
}

/// Reads numeric 1-D dataset `group`/`name` (its stored type of class `type_class`) converted
/// to `memory_type` (`element_size` bytes each) into `bytes`. @return its length.
hsize_t readNumberColumn(const Reader& r, hid_t parent, const std::string& group, const char* name,
                         hid_t memory_type, std::size_t element_size, H5T_class_t type_class,
                         std::vector<unsigned char>& bytes) {
  const std::string where = group + "/" + name;
  if (!hasLink(parent, name)) throw std::runtime_error(r.where + "no dataset " + where);
  Dataset d(r.check(H5Dopen2(parent, name, H5P_DEFAULT), where));
  const hsize_t n = rowsOf(r, d.get(), where, type_class);
  io::requireFitsInMemory(n * element_size, r.where + where);
  bytes.assign(static_cast<std::size_t>(n) * element_size, 0);
  if (n > 0) r.check(H5Dread(d.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data()), where);
  return n;
}

template <typename T>
std::vector<T> readNumbers(const Reader& r, hid_t parent, const std::string& group, const char* name,
                           hid_t memory_type, H5T_class_t type_class) {
  std::vector<unsigned char> bytes;
  const hsize_t n = readNumberColumn(r, parent, group, name, memory_type, sizeof(T), type_class, bytes);
  std::vector<T> out(static_cast<std::size_t>(n));
  if (n > 0) std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

}  // namespace

bool isHdf5File(const std::filesystem::path& path) {
  static constexpr unsigned char kSignature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  std::ifstream in(path, std::ios::binary);
  unsigned char head[8] = {};
  return in.read(reinterpret_cast<char*>(head), sizeof(head)) && std::memcmp(head, kSignature, sizeof(head)) == 0;
}

void writeRecordingHdf5(const Recording& recording, const std::filesystem::path& path,
                        const RecordingHdf5Volumes& volumes) {
  if (volumes.scan != nullptr && volumes.drilled != nullptr &&
      volumes.scan->geometry().dims != volumes.drilled->geometry().dims)
    throw std::invalid_argument("writeRecordingHdf5: the drilled field's grid differs from the scan's");
  silenceHdf5();
  io::PrivateOutput output(path);
  const Writer w{path.string()};
  if (output.inPlace())  // "-", /dev/stdout, a FIFO or a device: HDF5 writes by seeking in a file
    throw std::runtime_error("cannot write " + path.string() +
                             ": an HDF5 file must be a regular file (not the standard output, a pipe or a device)");
  {
    PropertyList order = creationOrdered(w, H5P_FILE_CREATE);
    File file(H5Fcreate(output.tempPath().c_str(), H5F_ACC_TRUNC, order.get(), H5P_DEFAULT));
    w.check(file.get(), "the file");
    const hid_t f = file.get();
    writeStringAttribute(w, f, "vh_format", kFormatName);
    writeNumberAttribute(w, f, "vh_layout_version", H5T_STD_I32LE, H5T_NATIVE_INT, kRecordingHdf5LayoutVersion);
    writeNumberAttribute(w, f, "recording_format_version", H5T_STD_U32LE, H5T_NATIVE_UINT32, recording.version);
    writeNumberAttribute(w, f, "chunks", H5T_STD_U64LE, H5T_NATIVE_UINT64, std::uint64_t{recording.chunks});
    writeNumberAttribute(w, f, "event_chunks", H5T_STD_U64LE, H5T_NATIVE_UINT64, std::uint64_t{recording.event_chunks});
    writeNumberAttribute(w, f, "dropped_records", H5T_STD_U64LE, H5T_NATIVE_UINT64, recording.dropped_records);
    writeNumberAttribute(w, f, "bytes_ignored", H5T_STD_U64LE, H5T_NATIVE_UINT64, recording.bytes_ignored);
    writeNumberAttribute(w, f, "damaged_regions", H5T_STD_U64LE, H5T_NATIVE_UINT64,
                         std::uint64_t{recording.damaged_regions});
    writeNumberAttribute(w, f, "ended", H5T_STD_U8LE, H5T_NATIVE_UINT8, static_cast<std::uint8_t>(recording.ended));
    writeNumberAttribute(w, f, "end_status", H5T_STD_U32LE, H5T_NATIVE_UINT32, recording.end_status);
    writeStringScalar(w, f, "metadata", recording.metadata_json);
    const nlohmann::json metadata = jsonNestingDepth(recording.metadata_json) <= kMaxRecordingJsonDepth
                                        ? nlohmann::json::parse(recording.metadata_json, nullptr, false)
                                        : nlohmann::json();
    if (metadata.is_object() && metadata.contains("scene")) writeStringScalar(w, f, "scene", metadata["scene"].dump());
    writeStrings(w, f, "warnings", recording.warnings);
    writeTicks(w, f, recording.records);
    writeEvents(w, f, recording.events);
    if (volumes.scan != nullptr || volumes.drilled != nullptr) {
      const double isovalue = recording.records.empty() ? std::nan("") : recording.records.back().isovalue;
      Group g = createGroup(w, f, "volume");
      if (volumes.scan != nullptr) writeVolume(w, g.get(), "scan", *volumes.scan, isovalue);
      if (volumes.drilled != nullptr) writeVolume(w, g.get(), "drilled", *volumes.drilled, isovalue);
    }
    w.check(H5Fflush(f, H5F_SCOPE_GLOBAL), "the file");
    w.check(H5Fclose(file.release()), "the file (closing it)");  // a failed close is a failed write
  }
  output.commit();
}

std::string writeRecordingHdf5WithVolume(const Recording& recording, const std::filesystem::path& path,
                                         const std::string& scene_metadata_json) {
  const LoadedScene scene = loadScene(
      sceneFromSessionMetadata(scene_metadata_json.empty() ? recording.metadata_json : scene_metadata_json));
  RecordingHdf5Volumes volumes;
  volumes.scan = scene.volume.field.get();
  std::string difference;
  std::shared_ptr<const haptics::ScalarVolume> drilled;
  if (scene.spec.drill.has_value() && !recording.records.empty()) drilled = drilledFieldAtEnd(scene, recording, difference);
  volumes.drilled = drilled.get();
  writeRecordingHdf5(recording, path, volumes);
  return difference;
}

Recording readRecordingHdf5(const std::filesystem::path& path) {
  silenceHdf5();
  const Reader r{path.string() + ": "};
  File file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  if (!file.valid()) throw std::runtime_error(r.where + "HDF5 cannot open it (damaged or not an HDF5 file)");
  const hid_t f = file.get();
  if (H5Aexists(f, "vh_format") <= 0 || readStringAttribute(r, f, "vh_format") != kFormatName)
    throw std::runtime_error(r.where + "an HDF5 file, but not a VolumeHaptics recording (no vh_format \"" +
                             kFormatName + "\")");
  const int layout = readNumberAttribute<int>(r, f, "vh_layout_version", H5T_NATIVE_INT);
  if (layout < 1 || layout > kRecordingHdf5LayoutVersion)
    throw std::runtime_error(r.where + "HDF5 layout version " + std::to_string(layout) + " (this program reads 1 to " +
                             std::to_string(kRecordingHdf5LayoutVersion) + ")");
  Recording rec;
  rec.version = readNumberAttribute<std::uint32_t>(r, f, "recording_format_version", H5T_NATIVE_UINT32);
  if (rec.version < 1 || rec.version > kRecordingFormatVersion)
    throw std::runtime_error(r.where + "recording format version " + std::to_string(rec.version) +
                             " (this program reads 1 to " + std::to_string(kRecordingFormatVersion) + ")");
  rec.chunks = static_cast<std::size_t>(readNumberAttribute<std::uint64_t>(r, f, "chunks", H5T_NATIVE_UINT64));
  rec.event_chunks = static_cast<std::size_t>(readNumberAttribute<std::uint64_t>(r, f, "event_chunks", H5T_NATIVE_UINT64));
  rec.dropped_records = readNumberAttribute<std::uint64_t>(r, f, "dropped_records", H5T_NATIVE_UINT64);
  rec.bytes_ignored = readNumberAttribute<std::uint64_t>(r, f, "bytes_ignored", H5T_NATIVE_UINT64);
  rec.damaged_regions =
      static_cast<std::size_t>(readNumberAttribute<std::uint64_t>(r, f, "damaged_regions", H5T_NATIVE_UINT64));
  rec.ended = readNumberAttribute<std::uint8_t>(r, f, "ended", H5T_NATIVE_UINT8) != 0;
  rec.end_status = readNumberAttribute<std::uint32_t>(r, f, "end_status", H5T_NATIVE_UINT32);
  rec.metadata_json = readStringScalar(r, f, "metadata");
  // The .vhrec reader's checks: metadata nested no deeper than it accepts, events likewise.
  requireMetadataDepth(r.where, rec.metadata_json);
  rec.warnings = readStrings(r, f, "", "warnings");

  if (!hasLink(f, "ticks")) throw std::runtime_error(r.where + "no group /ticks");
  Group ticks(r.check(H5Gopen2(f, "ticks", H5P_DEFAULT), "/ticks"));
  std::vector<unsigned char> bytes;
  bool first = true;
  for (const TickColumn& c : tickColumns()) {
    const H5T_class_t type_class = c.kind == TickColumn::kF64 ? H5T_FLOAT : H5T_INTEGER;
    const KindTypes types = typesOf(c.kind);
    const std::size_t size = types.size;
    const hsize_t n = readNumberColumn(r, ticks.get(), "/ticks", c.name, types.memory, size, type_class, bytes);
    if (first) {
      io::requireFitsInMemory(n * sizeof(TickRecord), r.where + "/ticks");
      rec.records.assign(static_cast<std::size_t>(n), TickRecord{});
      first = false;
    } else if (n != rec.records.size()) {
      throw std::runtime_error(r.where + "/ticks/" + c.name + " has " + std::to_string(n) + " rows, /ticks/t_s " +
                               std::to_string(rec.records.size()));
    }
    for (std::size_t i = 0; i < rec.records.size(); ++i)
      std::memcpy(reinterpret_cast<unsigned char*>(&rec.records[i]) + c.offset, bytes.data() + i * size, size);
  }

  if (!hasLink(f, "events")) throw std::runtime_error(r.where + "no group /events");
  Group events(r.check(H5Gopen2(f, "events", H5P_DEFAULT), "/events"));
  const auto t_s = readNumbers<double>(r, events.get(), "/events", "t_s", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  const auto tick = readNumbers<std::uint64_t>(r, events.get(), "/events", "tick", H5T_NATIVE_UINT64, H5T_INTEGER);
  const auto type = readStrings(r, events.get(), "/events", "type");
  const auto detail = readStrings(r, events.get(), "/events", "detail_json");
  if (tick.size() != t_s.size() || type.size() != t_s.size() || detail.size() != t_s.size())
    throw std::runtime_error(r.where + "the /events datasets differ in length");
  rec.events.reserve(t_s.size());
  for (std::size_t i = 0; i < t_s.size(); ++i) rec.events.push_back({t_s[i], tick[i], type[i], detail[i]});
  dropTooDeepEvents(r.where, rec);
  return rec;
}

}  // namespace vh::runtime
