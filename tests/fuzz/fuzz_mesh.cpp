// Fuzz target: tool meshes through vh::io::loadMesh's reading code in this process
// (detail::loadMeshInProcess, vh::io's private header: the application reads meshes in a worker
// process, where a crash would end the worker, not show here): VTK's STL, OBJ and PLY readers,
// then the project's triangulation, cleaning and checks.
// Input: byte 0 picks the format (0 mod 3: .stl, 1: .obj, 2: .ply); the rest is the file.
// Expected: a mesh or vh::io::LoadError. Anything else is a finding.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "loader_internal.h"  // app/io/src
#include "vh/io/volume_loader.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vh::fuzz::quietVtk();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* const kExt[] = {"in.stl", "in.obj", "in.ply"};
  const auto path = vh::fuzz::freshDir("mesh") / kExt[data[0] % 3];
  vh::fuzz::writeFile(path, data + 1, size - 1);
  try {
    const vh::haptics::TriangleMesh mesh = vh::io::detail::loadMeshInProcess(path, 1e-3);
    (void)mesh;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
