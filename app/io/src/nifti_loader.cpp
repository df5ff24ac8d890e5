// NIfTI-1 and NIfTI-2 loading (.nii, .nii.gz, and .hdr/.img pairs).
//
// vtkNIFTIImageReader reads the voxels (either version, either byte order, gzip or not, one file
// or a pair). The header is also read here, for three reasons:
//  - damaged headers get a clear error before VTK allocates anything: a short file, a bad
//    sizeof_hdr, a missing magic (Analyze 7.5, whose orientation is undefined), dimensions that are
//    0, negative or absurd, an unknown or non-scalar datatype, voxel data shorter than the header
//    announces (checked through the gzip stream for .gz files, so VTK never reads past the end);
//  - the voxel-to-world mapping is taken from the header's own numbers, as nibabel and ITK do:
//    the sform when sform_code > 0, else the qform when qform_code > 0, else the NIfTI-1
//    standard's method 1 (pixdim only). vtkNIFTIImageReader's matrices divide the sform by
//    pixdim and move offsets; only its slice order (GetQFac()) is used here;
//  - the length unit (xyzt_units) and the value scaling (scl_slope, scl_inter), which VTK reports
//    but does not apply.
// World: NIfTI's RAS+ [unit] becomes patient LPS [m] (p_LPS = diag(-1, -1, 1) p_RAS).
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vtkImageData.h>
#include <vtkNIFTIImageReader.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>
#include <zlib.h>

#include "loader_internal.h"
#include "nifti_internal.h"
#include "reader_checks.h"
#include "vh/io/patient_frames.h"
#include "vtk_error_capture.h"

namespace vh::io::detail {
namespace {

constexpr int kNifti1HeaderBytes = 348;
constexpr int kNifti2HeaderBytes = 540;
constexpr std::int64_t kMaxAxisVoxels = std::int64_t{1} << 20;
constexpr std::uintmax_t kMaxVolumeVoxels = std::uintmax_t{1} << 34;
constexpr int kIntentLabel = 1002;  // NIFTI_INTENT_LABEL: the values are labels

/// The header fields the loader uses, in native byte order, widened to NIfTI-2's types.
struct NiftiHeader {
  int version = 1;            ///< 1 or 2
  bool big_endian = false;
  bool single_file = true;    ///< "n+1" / "n+2": header and voxels in one file
  std::array<std::int64_t, 8> dim{};
  std::array<double, 8> pixdim{};
  int datatype = 0;
  std::int64_t vox_offset = 0;
  double scl_slope = 0.0;
  double scl_inter = 0.0;
  int qform_code = 0;
  int sform_code = 0;
  double quatern_b = 0.0, quatern_c = 0.0, quatern_d = 0.0;
  Eigen::Vector3d qoffset = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 3, 4> srow = Eigen::Matrix<double, 3, 4>::Zero();
  int xyzt_units = 0;
  int intent_code = 0;
};

/// The datatypes that are one scalar per voxel: code -> (name, bytes).
struct NiftiType {
  const char* name = nullptr;
  int bytes = 0;
};

NiftiType niftiType(int code) {
  switch (code) {
    case 2: return {"uint8", 1};
    case 4: return {"int16", 2};
    case 8: return {"int32", 4};
    case 16: return {"float32", 4};
    case 64: return {"float64", 8};
    case 256: return {"int8", 1};
    case 512: return {"uint16", 2};
    case 768: return {"uint32", 4};
    case 1024: return {"int64", 8};
    case 1280: return {"uint64", 8};
    default: return {};
  }
}

/// The name of a datatype that is valid NIfTI but not one scalar per voxel; nullptr otherwise.
const char* nonScalarTypeName(int code) {
  switch (code) {
    case 1: return "binary (1 bit)";
    case 32: return "complex64";
    case 128: return "rgb24";
    case 1536: return "float128";
    case 1792: return "complex128";
    case 2048: return "complex256";
    case 2304: return "rgba32";
    default: return nullptr;
  }
}

/// Reads a little- or big-endian value of type T at `offset` of `bytes`.
template <typename T>
T readAt(const std::vector<unsigned char>& bytes, std::size_t offset, bool big_endian) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, bytes.data() + offset, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  }
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

std::int32_t byteSwapped(std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  return static_cast<std::int32_t>((u >> 24) | ((u >> 8) & 0xff00u) | ((u << 8) & 0xff0000u) | (u << 24));
}

std::string lowerName(const fs::path& path) { return toLower(path.filename().string()); }

bool endsWith(const std::string& s, std::string_view tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

/// `path` with its name's ending `from` (lower case, as matched) replaced by `to`.
fs::path replaceEnding(const fs::path& path, std::size_t from_length, const std::string& to) {
  const std::string name = path.filename().string();
  return path.parent_path() / (name.substr(0, name.size() - from_length) + to);
}

/// The first of `candidates` that exists, else the first one.
fs::path firstExisting(const std::vector<fs::path>& candidates) {
  std::error_code ec;
  for (const auto& c : candidates) {
    if (fs::is_regular_file(c, ec)) return c;
  }
  return candidates.front();
}

/// The header file of a NIfTI path: itself, or the .hdr of an .img pair.
fs::path headerFileOf(const fs::path& path) {
  const std::string name = lowerName(path);
  if (endsWith(name, ".img")) return firstExisting({replaceEnding(path, 4, ".hdr"), replaceEnding(path, 4, ".hdr.gz")});
  if (endsWith(name, ".img.gz")) return firstExisting({replaceEnding(path, 7, ".hdr.gz"), replaceEnding(path, 7, ".hdr")});
  return path;
}

/// The voxel file of a pair's header (.img or .img.gz beside the .hdr).
fs::path imageFileOf(const fs::path& header) {
  const std::string name = lowerName(header);
  const std::size_t cut = endsWith(name, ".hdr.gz") ? 7 : 4;
  return firstExisting({replaceEnding(header, cut, ".img"), replaceEnding(header, cut, ".img.gz")});
}

/// A gzip stream (or a plain file, which zlib reads as is), closed on scope exit.
class GzFile {
 public:
  explicit GzFile(const fs::path& path) : f_(gzopen(path.string().c_str(), "rb")) {}
  ~GzFile() {
    if (f_ != nullptr) gzclose(f_);
  }
  GzFile(const GzFile&) = delete;
  GzFile& operator=(const GzFile&) = delete;
  bool ok() const { return f_ != nullptr; }
  /// Reads up to `n` bytes; the count read, or -1 with `error` set for a corrupt stream.
  long long read(void* buffer, std::size_t n, std::string& error) {
    long long total = 0;
    auto* out = static_cast<unsigned char*>(buffer);
    while (n > 0) {
      const unsigned chunk = static_cast<unsigned>(std::min<std::size_t>(n, 1u << 24));
      const int got = gzread(f_, out + total, chunk);
      if (got < 0) {
        int code = 0;
        const char* text = gzerror(f_, &code);
        error = text != nullptr ? text : "unknown zlib error";
        return -1;
      }
      if (got == 0) break;
      total += got;
      n -= static_cast<std::size_t>(got);
    }
    return total;
  }
  /// Skips up to `n` bytes; the count skipped, or -1 with `error` set.
  long long skip(std::uintmax_t n, std::string& error) {
    std::vector<unsigned char> buffer(1u << 20);
    std::uintmax_t total = 0;
    while (total < n) {
      const std::size_t want = static_cast<std::size_t>(std::min<std::uintmax_t>(n - total, buffer.size()));
      const long long got = read(buffer.data(), want, error);
      if (got < 0) return -1;
      if (got == 0) break;
      total += static_cast<std::uintmax_t>(got);
    }
    return static_cast<long long>(total);
  }

 private:
  gzFile f_;
};

bool isGzipName(const fs::path& path) { return endsWith(lowerName(path), ".gz"); }

/// The NIfTI-1 header's fields (`b`, its 348 bytes; `be`: big-endian) into `h`: the magic, the
/// dimensions, datatype, voxel sizes and offset, the value scale and the qform and sform.
/// @throws LoadError naming `path` for an Analyze 7.5 header (no NIfTI magic) or a vox_offset
///         that is no byte offset.
void readNifti1Fields(const std::vector<unsigned char>& b, bool be, const fs::path& path, NiftiHeader& h) {
  const char* magic = reinterpret_cast<const char*>(b.data() + 344);
  if (std::memcmp(magic, "n+1\0", 4) == 0) h.single_file = true;
  else if (std::memcmp(magic, "ni1\0", 4) == 0) h.single_file = false;
  else {
    fail(path, "an Analyze 7.5 header or a damaged NIfTI-1 header (no \"n+1\" or \"ni1\" magic): Analyze files "
               "do not say where the patient is; convert it to NIfTI (e.g. with nibabel or 3D Slicer)");
  }
  for (int i = 0; i < 8; ++i) h.dim[static_cast<std::size_t>(i)] = readAt<std::int16_t>(b, 40 + 2 * i, be);
  h.intent_code = readAt<std::int16_t>(b, 68, be);
  h.datatype = readAt<std::int16_t>(b, 70, be);
  for (int i = 0; i < 8; ++i) h.pixdim[static_cast<std::size_t>(i)] = readAt<float>(b, 76 + 4 * i, be);
  const double vox_offset = readAt<float>(b, 108, be);
  if (!std::isfinite(vox_offset) || vox_offset < 0.0 || vox_offset > 1e15 || vox_offset != std::floor(vox_offset)) {
    fail(path, "damaged NIfTI-1 header: vox_offset " + std::to_string(vox_offset) + " is not a byte offset");
  }
  h.vox_offset = static_cast<std::int64_t>(vox_offset);
  h.scl_slope = readAt<float>(b, 112, be);
  h.scl_inter = readAt<float>(b, 116, be);
  h.xyzt_units = b[123];
  h.qform_code = readAt<std::int16_t>(b, 252, be);
  h.sform_code = readAt<std::int16_t>(b, 254, be);
  h.quatern_b = readAt<float>(b, 256, be);
  h.quatern_c = readAt<float>(b, 260, be);
  h.quatern_d = readAt<float>(b, 264, be);
  for (int r = 0; r < 3; ++r) h.qoffset[r] = readAt<float>(b, static_cast<std::size_t>(268 + 4 * r), be);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) h.srow(r, c) = readAt<float>(b, static_cast<std::size_t>(280 + 16 * r + 4 * c), be);
  }
}

/// The NIfTI-2 header's fields (`b`, its 540 bytes; `be`: big-endian) into `h`, as
/// readNifti1Fields() for NIfTI-1.
/// @throws LoadError naming `path` for a damaged magic or a vox_offset that is no byte offset.
void readNifti2Fields(const std::vector<unsigned char>& b, bool be, const fs::path& path, NiftiHeader& h) {
  const char* magic = reinterpret_cast<const char*>(b.data() + 4);
  if (std::memcmp(magic, "n+2\0", 4) == 0) h.single_file = true;
  else if (std::memcmp(magic, "ni2\0", 4) == 0) h.single_file = false;
  else fail(path, "damaged NIfTI-2 header: no \"n+2\" or \"ni2\" magic");
  if (std::memcmp(magic + 4, "\r\n\032\n", 4) != 0) {
    fail(path, "damaged NIfTI-2 header: its magic's line-end bytes are altered (the file was copied as text?)");
  }
  h.datatype = readAt<std::int16_t>(b, 12, be);
  for (int i = 0; i < 8; ++i) h.dim[static_cast<std::size_t>(i)] = readAt<std::int64_t>(b, static_cast<std::size_t>(16 + 8 * i), be);
  for (int i = 0; i < 8; ++i) h.pixdim[static_cast<std::size_t>(i)] = readAt<double>(b, static_cast<std::size_t>(104 + 8 * i), be);
  h.vox_offset = readAt<std::int64_t>(b, 168, be);
  if (h.vox_offset < 0 || h.vox_offset > (std::int64_t{1} << 50)) {
    fail(path, "damaged NIfTI-2 header: vox_offset " + std::to_string(h.vox_offset) + " is not a byte offset");
  }
  h.scl_slope = readAt<double>(b, 176, be);
  h.scl_inter = readAt<double>(b, 184, be);
  h.qform_code = readAt<std::int32_t>(b, 344, be);
  h.sform_code = readAt<std::int32_t>(b, 348, be);
  h.quatern_b = readAt<double>(b, 352, be);
  h.quatern_c = readAt<double>(b, 360, be);
  h.quatern_d = readAt<double>(b, 368, be);
  for (int r = 0; r < 3; ++r) h.qoffset[r] = readAt<double>(b, static_cast<std::size_t>(376 + 8 * r), be);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) h.srow(r, c) = readAt<double>(b, static_cast<std::size_t>(400 + 32 * r + 8 * c), be);
  }
  h.xyzt_units = readAt<std::int32_t>(b, 500, be);
  h.intent_code = readAt<std::int32_t>(b, 504, be);
}

/// Dimensions: dim[0] axes, each at least 1 (the axes past dim[0] become 1); a scalar 3-D volume
/// (or the first of a 4-D series) of a sane voxel count.
/// @throws LoadError naming `path` otherwise.
void checkNiftiDimensions(const fs::path& path, NiftiHeader& h) {
  const std::int64_t ndim = h.dim[0];
  if (ndim < 1 || ndim > 7) {
    fail(path, "damaged NIfTI header: dim[0] (the number of dimensions) is " + std::to_string(ndim) +
                   ", not 1..7");
  }
  for (std::int64_t i = 1; i <= ndim; ++i) {
    const std::int64_t d = h.dim[static_cast<std::size_t>(i)];
    if (d <= 0) fail(path, "damaged NIfTI header: dim[" + std::to_string(i) + "] is " + std::to_string(d) + " (0 or negative)");
    if (d > kMaxAxisVoxels) {
      fail(path, "NIfTI dim[" + std::to_string(i) + "] = " + std::to_string(d) + " is absurd (over " +
                     std::to_string(kMaxAxisVoxels) + " voxels along one axis)");
    }
  }
  for (std::int64_t i = ndim + 1; i < 8; ++i) h.dim[static_cast<std::size_t>(i)] = 1;
  if (ndim < 3 || h.dim[3] < 2) {
    fail(path, "not a 3-D volume: a " + std::to_string(ndim) + "-D NIfTI image of " + std::to_string(h.dim[1]) + "x" +
                   std::to_string(h.dim[2]) + "x" + std::to_string(h.dim[3]) + " voxels");
  }
  if (h.dim[5] > 1 || h.dim[6] > 1 || h.dim[7] > 1) {
    fail(path, "has " + std::to_string(h.dim[5] * h.dim[6] * h.dim[7]) +
                   " values per voxel (NIfTI dim[5..7]: a vector, tensor or displacement field); only scalar volumes "
                   "are supported");
  }
  const std::uintmax_t voxels = static_cast<std::uintmax_t>(h.dim[1]) * static_cast<std::uintmax_t>(h.dim[2]) *
                                static_cast<std::uintmax_t>(h.dim[3]);
  if (voxels > kMaxVolumeVoxels) fail(path, "NIfTI dimensions announce an absurd number of voxels (" + std::to_string(voxels) + ")");
}

/// A scalar datatype this reader knows, and finite voxel sizes.
/// @throws LoadError naming `path` otherwise.
void checkNiftiDatatypeAndSpacing(const fs::path& path, const NiftiHeader& h) {
  if (niftiType(h.datatype).bytes == 0) {
    if (const char* name = nonScalarTypeName(h.datatype)) {
      fail(path, std::string("has NIfTI datatype ") + name + "; only scalar volumes (integers, float32, float64) are supported");
    }
    fail(path, "damaged NIfTI header: unknown datatype " + std::to_string(h.datatype));
  }
  for (int i = 1; i <= 3; ++i) {
    if (!std::isfinite(h.pixdim[static_cast<std::size_t>(i)])) {
      fail(path, "damaged NIfTI header: pixdim[" + std::to_string(i) + "] (a voxel size) is not a number");
    }
  }
}

/// Reads and checks the header of `header_path`.
/// @throws LoadError naming `path` for a short file, a bad sizeof_hdr or magic, bad dimensions
///         or an unsupported datatype.
NiftiHeader readHeader(const fs::path& path, const fs::path& header_path) {
  GzFile in(header_path);
  if (!in.ok()) fail(path, "cannot be opened for reading");
  std::vector<unsigned char> b(kNifti2HeaderBytes, 0);
  std::string zerror;
  const long long got = in.read(b.data(), b.size(), zerror);
  if (got < 0) fail(path, "corrupt gzip data in the NIfTI header (" + zerror + ")");
  if (got < 4) fail(path, "truncated: " + std::to_string(got) + " bytes, shorter than a NIfTI header (348 bytes)");

  NiftiHeader h;
  std::int32_t sizeof_hdr = 0;
  std::memcpy(&sizeof_hdr, b.data(), 4);
  const bool native_little = std::endian::native == std::endian::little;
  if (sizeof_hdr == kNifti1HeaderBytes || sizeof_hdr == kNifti2HeaderBytes) {
    h.big_endian = !native_little;
  } else if (byteSwapped(sizeof_hdr) == kNifti1HeaderBytes || byteSwapped(sizeof_hdr) == kNifti2HeaderBytes) {
    h.big_endian = native_little;
    sizeof_hdr = byteSwapped(sizeof_hdr);
  } else {
    fail(path, "not a NIfTI file or a damaged header: sizeof_hdr is " + std::to_string(sizeof_hdr) +
                   " (348 for NIfTI-1, 540 for NIfTI-2)");
  }
  h.version = sizeof_hdr == kNifti1HeaderBytes ? 1 : 2;
  if (got < sizeof_hdr) {
    fail(path, "truncated NIfTI-" + std::to_string(h.version) + " header: " + std::to_string(got) + " of " +
                   std::to_string(sizeof_hdr) + " bytes");
  }
  const bool be = h.big_endian;
  if (h.version == 1) readNifti1Fields(b, be, path, h);
  else readNifti2Fields(b, be, path, h);
  if (h.single_file && h.vox_offset < sizeof_hdr) {
    fail(path, "damaged NIfTI header: vox_offset " + std::to_string(h.vox_offset) + " lies inside the " +
                   std::to_string(sizeof_hdr) + "-byte header");
  }

  checkNiftiDimensions(path, h);
  checkNiftiDatatypeAndSpacing(path, h);
  return h;
}

/// Checks that the voxels of the first volume are all there: the file size for a plain file,
/// the decompressed length for gzip (streamed, nothing kept).
/// @throws LoadError naming `path` when they are not.
void checkVoxelData(const fs::path& path, const fs::path& data_path, const NiftiHeader& h) {
  const std::uintmax_t expected = static_cast<std::uintmax_t>(h.dim[1]) * static_cast<std::uintmax_t>(h.dim[2]) *
                                  static_cast<std::uintmax_t>(h.dim[3]) *
                                  static_cast<std::uintmax_t>(niftiType(h.datatype).bytes);
  const auto start = static_cast<std::uintmax_t>(h.vox_offset);
  const std::string where = h.single_file ? std::string() : " in " + data_path.filename().string();
  std::error_code ec;
  if (!fs::is_regular_file(data_path, ec)) fail(path, "the voxel file " + data_path.filename().string() + " is missing");
  if (!isGzipName(data_path)) {
    const auto size = fileSize(data_path);
    if (!size) fail(path, "cannot read the size of " + data_path.filename().string());
    const std::uintmax_t available = *size > start ? *size - start : 0;
    if (available < expected) {
      fail(path, "truncated: expected " + std::to_string(expected) + " bytes of voxel data" + where + ", found " +
                     std::to_string(available));
    }
    return;
  }
  GzFile in(data_path);
  if (!in.ok()) fail(path, "cannot open " + data_path.filename().string());
  std::string zerror;
  const long long got = in.skip(start + expected, zerror);
  if (got < 0) fail(path, "corrupt gzip voxel data" + where + " (" + zerror + ")");
  if (static_cast<std::uintmax_t>(got) < start + expected) {
    const std::uintmax_t available = static_cast<std::uintmax_t>(got) > start ? static_cast<std::uintmax_t>(got) - start : 0;
    fail(path, "truncated: expected " + std::to_string(expected) + " bytes of voxel data" + where +
                   " after decompression, found " + std::to_string(available));
  }
}

/// Metres per unit of xyzt_units' spatial part; 0 (unknown) is read as millimetres with a notice.
double lengthUnitToM(const NiftiHeader& h, const fs::path& path, std::vector<std::string>& notices) {
  switch (h.xyzt_units & 0x07) {
    case 0:
      notices.push_back("the NIfTI header gives no length unit (xyzt_units): millimetres assumed");
      return 1e-3;
    case 1: return 1.0;   // NIFTI_UNITS_METER
    case 2: return 1e-3;  // NIFTI_UNITS_MM
    case 3: return 1e-6;  // NIFTI_UNITS_MICRON
    default:
      fail(path, "damaged NIfTI header: unknown length unit code " + std::to_string(h.xyzt_units & 0x07) +
                     " in xyzt_units");
  }
}

/// The qform: RAS [unit] of file voxel (i, j, k) = R diag(pixdim1, pixdim2, qfac pixdim3) ijk + qoffset
/// (NIfTI-1 method 2; the quaternion's a = sqrt(1 - b^2 - c^2 - d^2), as niftilib: when b^2 + c^2
/// + d^2 exceeds 1 the rotation is a half turn about (b, c, d) normalised).
Eigen::Matrix<double, 3, 4> qformAffine(const NiftiHeader& h) {
  double b = h.quatern_b, c = h.quatern_c, d = h.quatern_d;
  double a = 1.0 - (b * b + c * c + d * d);
  if (a < 1e-7) {
    const double n = std::sqrt(b * b + c * c + d * d);
    if (n > 0.0) {
      b /= n;
      c /= n;
      d /= n;
    }
    a = 0.0;
  } else {
    a = std::sqrt(a);
  }
  Eigen::Matrix3d R;
  R << a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c),  //
      2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b),   //
      2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b;
  const double qfac = h.pixdim[0] < 0.0 ? -1.0 : 1.0;  // as vtkNIFTIImageReader and niftilib
  Eigen::Matrix<double, 3, 4> A;
  A.leftCols<3>() = R * Eigen::Vector3d(h.pixdim[1], h.pixdim[2], qfac * h.pixdim[3]).asDiagonal();
  A.col(3) = h.qoffset;
  return A;
}

/// True when the 3 x 3 part's columns are orthogonal (what the field's grid can represent).
bool orthogonalColumns(const Eigen::Matrix<double, 3, 4>& A) {
  Eigen::Matrix3d n = A.leftCols<3>();
  for (int c = 0; c < 3; ++c) {
    const double len = n.col(c).norm();
    if (!(len > 0.0) || !std::isfinite(len)) return false;
    n.col(c) /= len;
  }
  return (n.transpose() * n).isApprox(Eigen::Matrix3d::Identity(), 1e-4);
}

/// The voxel-to-RAS affine of the file's voxel indices [file unit]: the sform when sform_code >
/// 0 (unless it is sheared and a qform is there), else the qform when qform_code > 0, else
/// method 1 (pixdim only, no rotation or offset).
Eigen::Matrix<double, 3, 4> fileAffine(const NiftiHeader& h, const fs::path& path, std::vector<std::string>& notices) {
  if (h.sform_code > 0) {
    if (!h.srow.allFinite()) fail(path, "damaged NIfTI header: the sform (srow_x/y/z) holds a value that is not a number");
    if (orthogonalColumns(h.srow) || h.qform_code <= 0) return h.srow;
    notices.push_back("the NIfTI sform is sheared, which a voxel grid cannot hold: placed by the qform instead");
  }
  if (h.qform_code > 0) {
    if (!std::isfinite(h.quatern_b) || !std::isfinite(h.quatern_c) || !std::isfinite(h.quatern_d) ||
        !h.qoffset.allFinite()) {
      fail(path, "damaged NIfTI header: the qform (quatern_b/c/d, qoffset) holds a value that is not a number");
    }
    return qformAffine(h);
  }
  notices.push_back("the NIfTI header has neither an sform nor a qform (both codes 0): placed by the voxel size "
                    "only, voxel (0, 0, 0) at the origin, axes along R, A, S");
  Eigen::Matrix<double, 3, 4> A = Eigen::Matrix<double, 3, 4>::Zero();
  for (int c = 0; c < 3; ++c) A(c, c) = h.pixdim[static_cast<std::size_t>(c + 1)];
  return A;
}

}  // namespace

bool isNiftiFileName(const fs::path& path) {
  const std::string name = lowerName(path);
  for (const char* ending : {".nii", ".nii.gz", ".hdr", ".hdr.gz"}) {
    if (endsWith(name, ending)) return true;
  }
  if (endsWith(name, ".img") || endsWith(name, ".img.gz")) {
    std::error_code ec;
    return fs::is_regular_file(headerFileOf(path), ec);
  }
  return false;
}

bool hasNiftiMagic(std::string_view head) {
  if (head.size() >= 348 && (head.substr(344, 4) == std::string_view("n+1\0", 4) ||
                             head.substr(344, 4) == std::string_view("ni1\0", 4))) {
    return true;
  }
  return head.size() >= 12 && (head.substr(4, 4) == std::string_view("n+2\0", 4) ||
                                head.substr(4, 4) == std::string_view("ni2\0", 4));
}

bool isNiftiLabelMap(const fs::path& path) {
  try {
    const NiftiHeader h = readHeader(path, headerFileOf(path));
    return h.intent_code == kIntentLabel;
  } catch (const LoadError&) {
    return false;
  }
}

LoadedVolume loadNifti(const fs::path& path) {
  const fs::path header_path = headerFileOf(path);
  const NiftiHeader h = readHeader(path, header_path);
  const fs::path data_path = h.single_file ? header_path : imageFileOf(header_path);
  std::error_code link_ec;
  if (!h.single_file && fs::symlink_status(data_path, link_ec).type() != fs::file_type::not_found) {
    // A pair's voxel file follows the rules of every detached data file (NRRD, MetaImage): in
    // the header's folder once links are resolved, and a regular file; a .img linked to
    // /etc/shadow is not read as voxels.
    detail::requireBesideHeader(header_path, data_path);
    detail::requireRegularFile(data_path, header_path);
  }
  checkVoxelData(path, data_path, h);

  VolumeInfo info;
  const double to_m = lengthUnitToM(h, path, info.notices);
  const Eigen::Matrix<double, 3, 4> A = fileAffine(h, path, info.notices);

  VtkErrorCapture capture;
  auto reader = vtkSmartPointer<vtkNIFTIImageReader>::New();
  capture.watch(reader);
  reader->SetFileName(header_path.string().c_str());
  reader->Update();
  if (capture.hasErrors()) fail(path, "voxel data could not be read (" + capture.firstError() + ")");
  vtkImageData* out = reader->GetOutput();
  if (out == nullptr || out->GetPointData()->GetScalars() == nullptr) fail(path, "no voxel data was read");

  // vtkNIFTIImageReader keeps the voxel indices right-handed: with a qform's qfac of -1 (or,
  // without a qform, an sform of negative determinant) its slice K is the file's slice
  // nz - 1 - K. The affine follows: k = nz - 1 - K.
  Eigen::Matrix<double, 3, 4> A_vtk = A;
  if (reader->GetQFac() < 0.0) {
    A_vtk.col(3) = A.col(3) + static_cast<double>(h.dim[3] - 1) * A.col(2);
    A_vtk.col(2) = -A.col(2);
  }
  Eigen::Matrix3d direction_RAS;
  Eigen::Vector3d spacing;
  splitAxes(A_vtk.leftCols<3>(), path, direction_RAS, spacing);
  const Eigen::Matrix3d lps_from_ras = lpsFromRasMatrix();

  RawVolume raw;
  raw.image = out;
  raw.geometry.spacing_m = spacing * to_m;
  raw.geometry.direction_W = lps_from_ras * direction_RAS;
  raw.geometry.origin_W_m = lps_from_ras * A_vtk.col(3) * to_m;
  if (!raw.geometry.origin_W_m.allFinite() || !raw.geometry.spacing_m.allFinite()) {
    fail(path, "damaged NIfTI header: the voxel-to-world mapping is not finite");
  }
  // scl_slope 0 (or not a number) means unscaled, as nibabel and niftilib read it.
  if (std::isfinite(h.scl_slope) && h.scl_slope != 0.0) {
    raw.value_scale = h.scl_slope;
    raw.value_offset = std::isfinite(h.scl_inter) ? h.scl_inter : 0.0;
  }
  raw.info = std::move(info);
  raw.info.format = h.version == 1 ? "NIfTI-1" : "NIfTI-2";
  raw.info.description = path.filename().string();
  if (h.dim[0] >= 4 && h.dim[4] > 1) {
    raw.info.phase_count = static_cast<int>(h.dim[4]);
    raw.info.notices.push_back("a 4-D NIfTI of " + std::to_string(h.dim[4]) + " volumes: the first one loaded");
  }
  return finishVolume(std::move(raw), path);
}

}  // namespace vh::io::detail
