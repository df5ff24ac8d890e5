// Format dispatch for loadVolume, and the helpers shared by the format loaders.
#include "vh/io/volume_loader.h"

#include <cstdio>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <system_error>

#include <Eigen/Dense>

#include "loader_internal.h"
#include "nifti_internal.h"

namespace vh::io {
namespace detail {

void fail(const fs::path& path, const std::string& problem) {
  throw LoadError(path.string() + ": " + problem);
}

std::string trim(std::string_view s) {
  std::size_t b = 0;
  std::size_t e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b])) != 0) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1])) != 0) --e;
  return std::string(s.substr(b, e - b));
}

std::string toLower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::vector<std::string> splitWords(std::string_view s) {
  std::vector<std::string> words;
  std::istringstream in{std::string(s)};
  std::string w;
  while (in >> w) words.push_back(w);
  return words;
}

std::optional<double> parseDouble(std::string_view s) {
  const std::string t = trim(s);
  if (t.empty()) return std::nullopt;
  const char* begin = t.c_str();
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end != begin + t.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<long long> parseInt(std::string_view s) {
  const std::string t = trim(s);
  long long v = 0;
  const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || ptr != t.data() + t.size() || t.empty()) return std::nullopt;
  return v;
}

std::optional<std::uintmax_t> fileSize(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return std::nullopt;
  return size;
}

void splitAxes(const Eigen::Matrix3d& axes, const fs::path& path, Eigen::Matrix3d& direction_W,
               Eigen::Vector3d& spacing) {
  for (int c = 0; c < 3; ++c) {
    const double n = axes.col(c).norm();
    if (!(n > 0.0) || !std::isfinite(n)) {
      fail(path, "grid axis " + std::to_string(c) + " has zero or invalid length");
    }
    spacing[c] = n;
    direction_W.col(c) = axes.col(c) / n;
  }
  const Eigen::Matrix3d gram = direction_W.transpose() * direction_W;
  if (!gram.isApprox(Eigen::Matrix3d::Identity(), 1e-4)) {
    std::ostringstream os;
    os << "grid axes are not orthogonal (sheared or tilted grid, e.g. gantry tilt), which is not "
          "supported; largest axis cosine "
       << (gram - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    fail(path, os.str());
  }
  // Remove rounding noise so the core's orthonormality check passes exactly enough.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(direction_W, Eigen::ComputeFullU | Eigen::ComputeFullV);
  direction_W = svd.matrixU() * svd.matrixV().transpose();
}

std::optional<double> lengthUnitToMetres(std::string_view unit) {
  std::string u = toLower(trim(unit));
  if (u.size() >= 2 && u.front() == '"' && u.back() == '"') u = trim(u.substr(1, u.size() - 2));
  if (u.empty() || u == "mm" || u == "millimeter" || u == "millimetre" || u == "millimeters" ||
      u == "millimetres") {
    return 1e-3;
  }
  if (u == "m" || u == "meter" || u == "metre" || u == "meters" || u == "metres") return 1.0;
  if (u == "cm") return 1e-2;
  if (u == "um" || u == "micron" || u == "microns" || u == "\xc2\xb5m" || u == "\xce\xbcm") {
    return 1e-6;
  }
  return std::nullopt;
}

std::string dimsString(const std::array<int, 3>& dims) {
  return std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" + std::to_string(dims[2]);
}

}  // namespace detail

namespace {

namespace fs = std::filesystem;

enum class Format { kDicom, kNrrd, kMetaImage, kNifti, kUnknown };

/// Guesses the format from the extension, then from the first bytes.
Format detectFormat(const fs::path& path) {
  const std::string ext = detail::toLower(path.extension().string());
  if (ext == ".nrrd" || ext == ".nhdr") return Format::kNrrd;
  if (ext == ".mha" || ext == ".mhd") return Format::kMetaImage;
  if (ext == ".dcm" || ext == ".dicom" || ext == ".ima") return Format::kDicom;
  if (detail::isNiftiFileName(path)) return Format::kNifti;

  std::ifstream in(path, std::ios::binary);
  std::array<char, 1024> head{};
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  const auto n = static_cast<std::size_t>(in.gcount());
  const std::string_view text(head.data(), n);
  if (text.substr(0, 7) == "NRRD000") return Format::kNrrd;
  if (detail::hasNiftiMagic(text)) return Format::kNifti;
  if (n >= 132 && text.substr(128, 4) == "DICM") return Format::kDicom;
  if (text.find("ObjectType") != std::string_view::npos ||
      (text.find("NDims") != std::string_view::npos &&
       text.find("DimSize") != std::string_view::npos)) {
    return Format::kMetaImage;
  }
  // Files without an extension are often DICOM without a preamble (e.g. "I10"); let the DICOM
  // scanner decide.
  if (ext.empty()) return Format::kDicom;
  return Format::kUnknown;
}

}  // namespace

namespace {

/// `v` when its voxels are at least kMinVoxelSide_m on every side, else a LoadError naming the
/// file: a voxel of 1e-30 m (a hostile ElementSpacing or pixdim) made every later step that
/// walks the volume in voxels (the tool's placement, the trajectory's ray) run for hours.
LoadedVolume withSaneVoxels(const fs::path& path, LoadedVolume v) {
  if (v.field == nullptr) return v;
  const Eigen::Vector3d& s = v.field->geometry().spacing_m;
  if (!(s.minCoeff() >= kMinVoxelSide_m * (1.0 - 1e-9))) {  // 1 um itself, rounded either way, loads
    char text[200];
    std::snprintf(text, sizeof text,
                  "a voxel side of %.3g mm (%.3g x %.3g x %.3g mm): below %.3g mm (1 um), no scanner's; "
                  "nothing was loaded",
                  1e3 * s.minCoeff(), 1e3 * s.x(), 1e3 * s.y(), 1e3 * s.z(), 1e3 * kMinVoxelSide_m);
    detail::fail(path, text);
  }
  return v;
}

}  // namespace

/// The volume of `path` as its format gives it (loadVolume() without the voxel-size check).
static LoadedVolume loadUnchecked(const std::filesystem::path& path, const VolumeLoadOptions& options) {
  std::error_code ec;
  if (path.empty()) throw LoadError("(empty path): no file or folder given");
  const auto status = fs::status(path, ec);
  if (ec || !fs::exists(status)) detail::fail(path, "no such file or folder");
  if (fs::is_directory(status)) return detail::loadDicom(path, options);
  if (!fs::is_regular_file(status)) detail::fail(path, "not a regular file or folder");
  const auto size = detail::fileSize(path);
  if (!size) detail::fail(path, "cannot read the file size");
  if (*size == 0) detail::fail(path, "empty file (0 bytes): not a volume");
  {
    std::ifstream probe(path, std::ios::binary);
    if (!probe) detail::fail(path, "cannot be opened for reading (permissions?)");
  }
  switch (detectFormat(path)) {
    case Format::kDicom:
      return detail::loadDicom(path, options);
    case Format::kNrrd:
      return detail::loadFileIsolated(path, options, [&] { return detail::loadNrrd(path, options.nrrd_layer); });
    case Format::kMetaImage:
      return detail::loadFileIsolated(path, options, [&] { return detail::loadMetaImage(path); });
    case Format::kNifti:
      return detail::loadFileIsolated(path, options, [&] { return detail::loadNifti(path); });
    case Format::kUnknown:
      break;
  }
  detail::fail(path,
               "not a volume: unrecognised format (expected a DICOM folder or file, NRRD "
               ".nrrd/.nhdr, MetaImage .mha/.mhd, or NIfTI .nii/.nii.gz/.hdr)");
}

LoadedVolume loadVolume(const std::filesystem::path& path, const VolumeLoadOptions& options) {
  return withSaneVoxels(path, loadUnchecked(path, options));
}

std::string volumeFileDialogFilter() {
  return "Volumes (*.nrrd *.nhdr *.mha *.mhd *.nii *.nii.gz *.hdr *.dcm);;NRRD (*.nrrd *.nhdr);;"
         "MetaImage (*.mha *.mhd);;NIfTI (*.nii *.nii.gz *.hdr);;DICOM file of a series (*.dcm *);;All files (*)";
}

std::string meshFileDialogFilter() {
  return "Meshes (*.stl *.obj *.ply);;STL (*.stl);;Wavefront OBJ (*.obj);;PLY (*.ply);;"
         "All files (*)";
}

}  // namespace vh::io
