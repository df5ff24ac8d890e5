// vh-make-datasets: writes the synthetic volumes of vh::datasets as NRRD files (attached header,
// raw, little endian, millimetres) and the built-in tool meshes as OBJ files (metres), plus a
// manifest.json listing each file with its isovalue. Standard library only (no VTK): the
// datasets folder builds with the core alone.
//
// Usage: vh-make-datasets --out DIR [--block-dims N]

#include <bit>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "vh/datasets/synthetic.h"

namespace fs = std::filesystem;
using vh::haptics::ScalarVolume;
using vh::haptics::TriangleMesh;
using vh::haptics::VoxelType;

namespace {

const char* nrrdType(VoxelType type) {
  switch (type) {
    case VoxelType::kUInt8: return "uint8";
    case VoxelType::kInt16: return "int16";
    case VoxelType::kUInt16: return "uint16";
    case VoxelType::kFloat32: return "float";
  }
  return "uint8";
}

std::string vectorText(const Eigen::Vector3d& v) {
  std::ostringstream out;
  out << std::setprecision(17) << '(' << v.x() << ',' << v.y() << ',' << v.z() << ')';
  return out.str();
}

/// Writes `volume` as a NRRD with an attached header; geometry in millimetres in a generic
/// right-handed space (W itself). Values are the raw voxels (scale 1, offset 0 in vh::datasets).
void writeNrrd(const ScalarVolume& volume, const std::string& name, double isovalue, const fs::path& path) {
  static_assert(std::endian::native == std::endian::little, "the NRRD writer assumes a little-endian host");
  if (volume.valueScale() != 1.0 || volume.valueOffset() != 0.0) {
    throw std::runtime_error(name + ": value scale/offset other than 1/0 cannot be written as plain NRRD");
  }
  const auto& g = volume.geometry();
  const Eigen::Matrix3d axes_mm = g.direction_W * (g.spacing_m * 1e3).asDiagonal();
  std::ostringstream header;
  header << "NRRD0004\n"
         << "# VolumeHaptics synthetic volume '" << name << "' (vh-make-datasets); isosurface at F = "
         << std::setprecision(17) << isovalue << "\n"
         << "content: " << name << "\n"
         << "type: " << nrrdType(volume.voxelType()) << "\n"
         << "dimension: 3\n"
         << "space: 3D-right-handed\n"
         << "sizes: " << g.dims[0] << ' ' << g.dims[1] << ' ' << g.dims[2] << "\n"
         << "space directions: " << vectorText(axes_mm.col(0)) << ' ' << vectorText(axes_mm.col(1)) << ' '
         << vectorText(axes_mm.col(2)) << "\n"
         << "space origin: " << vectorText(g.origin_W_m * 1e3) << "\n"
         << "space units: \"mm\" \"mm\" \"mm\"\n"
         << "kinds: domain domain domain\n"
         << "endian: little\n"
         << "encoding: raw\n"
         << "\n";
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error(path.string() + ": cannot write");
  const std::string text = header.str();
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.write(reinterpret_cast<const char*>(volume.bytes().data()), static_cast<std::streamsize>(volume.bytes().size()));
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

/// Writes a triangle mesh as OBJ (metres, 1-based indices).
void writeObj(const TriangleMesh& mesh, const std::string& name, const fs::path& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write");
  out << "# VolumeHaptics built-in tool '" << name << "' (vh-make-datasets), metres, tool frame T\n"
      << "o " << name << "\n"
      << std::setprecision(9);
  for (const Eigen::Vector3d& v : mesh.vertices_T_m) out << "v " << v.x() << ' ' << v.y() << ' ' << v.z() << '\n';
  for (const auto& t : mesh.triangles) out << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

void usage(std::ostream& out) {
  out << "usage: vh-make-datasets --out DIR [--block-dims N]\n"
         "Writes the synthetic volumes (NRRD) and built-in tool meshes (OBJ) of vh::datasets into DIR.\n";
}

}  // namespace

int main(int argc, char** argv) {
  fs::path out_dir;
  int block_dims = 256;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--out" || arg == "-o") && i + 1 < argc) {
      out_dir = argv[++i];
    } else if (arg == "--block-dims" && i + 1 < argc) {
      block_dims = std::atoi(argv[++i]);
    } else if (arg == "--help" || arg == "-h") {
      usage(std::cout);
      return 0;
    } else {
      std::cerr << "vh-make-datasets: unexpected argument '" << arg << "'\n";
      usage(std::cerr);
      return 2;
    }
  }
  if (out_dir.empty()) {
    usage(std::cerr);
    return 2;
  }
  try {
    fs::create_directories(out_dir);
    std::ostringstream manifest;
    manifest << std::setprecision(17) << "{\n  \"volumes\": [\n";
    const char* volumes[] = {"plane", "sphere", "thin-plate", "block-with-hole"};
    bool first = true;
    for (const char* name : volumes) {
      const ScalarVolume volume = std::strcmp(name, "block-with-hole") == 0
                                      ? vh::datasets::makeBlockWithHoleVolume(block_dims)
                                      : vh::datasets::makeBuiltinVolume(name);
      const double iso = vh::datasets::builtinIsovalue(name);
      const std::string file = std::string(name) + ".nrrd";
      writeNrrd(volume, name, iso, out_dir / file);
      const auto& d = volume.geometry().dims;
      manifest << (first ? "" : ",\n") << "    {\"name\": \"" << name << "\", \"file\": \"" << file
               << "\", \"isovalue\": " << iso << ", \"dims\": [" << d[0] << ", " << d[1] << ", " << d[2] << "]}";
      first = false;
      std::cout << "vh-make-datasets: " << (out_dir / file).string() << '\n';
    }
    manifest << "\n  ],\n  \"tools\": [\n";
    const char* tools[] = {"peg", "probe", "drill", "sphere"};
    first = true;
    for (const char* name : tools) {
      const std::string file = std::string(name) + ".obj";
      writeObj(vh::datasets::makeBuiltinTool(name), name, out_dir / file);
      manifest << (first ? "" : ",\n") << "    {\"name\": \"" << name << "\", \"file\": \"" << file
               << "\", \"units\": \"m\"}";
      first = false;
      std::cout << "vh-make-datasets: " << (out_dir / file).string() << '\n';
    }
    manifest << "\n  ]\n}\n";
    std::ofstream m(out_dir / "manifest.json");
    m << manifest.str();
    if (!m) throw std::runtime_error((out_dir / "manifest.json").string() + ": write failed");
  } catch (const std::exception& e) {
    std::cerr << "vh-make-datasets: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
