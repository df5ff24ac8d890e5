#include "vh/io/nrrd_writer.h"

#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "vh/io/private_files.h"

namespace vh::io {

void writeNrrd(const std::filesystem::path& path, const NrrdVolume& v) {
  static const std::map<std::string, std::size_t> kSize{{"uchar", 1}, {"short", 2}, {"ushort", 2}, {"float", 4}};
  const auto size = kSize.find(v.type);
  if (size == kSize.end()) throw std::runtime_error(path.string() + ": NRRD type '" + v.type + "' is not written");
  if (v.dims[0] < 1 || v.dims[1] < 1 || v.dims[2] < 1 || v.voxels == nullptr)
    throw std::runtime_error(path.string() + ": no voxels to write");
  std::ostringstream h;
  h.precision(17);
  h << "NRRD0004\n# Written by VolumeHaptics\ntype: " << v.type << "\ndimension: 3\n"
    << "space: left-posterior-superior\nsizes: " << v.dims[0] << " " << v.dims[1] << " " << v.dims[2] << "\n"
    << "space directions:";
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d d = v.direction_W.col(a) * (v.spacing_m[a] * 1e3);
    h << " (" << d.x() << "," << d.y() << "," << d.z() << ")";
  }
  const Eigen::Vector3d o = v.origin_W_m * 1e3;
  h << "\nkinds: domain domain domain\nendian: little\nencoding: raw\n"
    << "space origin: (" << o.x() << "," << o.y() << "," << o.z() << ")\n";
  for (const auto& [key, value] : v.key_values) h << key << ":=" << value << "\n";
  h << "\n";
  // 0600 (a drilled scan is the patient's), renamed into place only when whole.
  std::optional<PrivateOutput> file;
  try {
    file.emplace(path);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path.string() + ": cannot open the file for writing (" + e.what() + ")");
  }
  std::ostream& out = file->stream();
  const std::string header = h.str();
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  const std::size_t bytes = static_cast<std::size_t>(v.dims[0]) * v.dims[1] * v.dims[2] * size->second;
  out.write(static_cast<const char*>(v.voxels), static_cast<std::streamsize>(bytes));
  try {
    file->commit();
  } catch (const std::runtime_error&) {
    throw std::runtime_error(path.string() + ": the write failed (disk full?)");
  }
}

}  // namespace vh::io
