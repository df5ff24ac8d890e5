// Tool mesh loading (STL, OBJ, PLY) through VTK.
#include <cmath>
#include <fstream>

#include <vtkAbstractPolyDataReader.h>
#include <vtkCellArray.h>
#include <vtkCleanPolyData.h>
#include <vtkIdList.h>
#include <vtkOBJReader.h>
#include <vtkPLYReader.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataAlgorithm.h>
#include <vtkSTLReader.h>
#include <vtkSmartPointer.h>
#include <vtkTriangleFilter.h>

#include "loader_internal.h"
#include "vh/io/volume_loader.h"
#include "vtk_error_capture.h"

namespace vh::io {

haptics::TriangleMesh detail::loadMeshInProcess(const std::filesystem::path& path, double scale_to_m) {
  namespace fs = std::filesystem;
  using detail::fail;
  if (!(scale_to_m > 0.0) || !std::isfinite(scale_to_m)) {
    fail(path, "invalid scale_to_m " + std::to_string(scale_to_m) +
                   " (must be positive and finite)");
  }
  std::error_code ec;
  if (!fs::exists(path, ec)) fail(path, "no such file");
  if (!fs::is_regular_file(path, ec)) fail(path, "not a regular file");
  if (detail::fileSize(path).value_or(0) == 0) fail(path, "empty file (0 bytes): not a mesh");
  {
    std::ifstream probe(path, std::ios::binary);
    if (!probe) fail(path, "cannot be opened for reading (permissions?)");
  }

  const std::string ext = detail::toLower(path.extension().string());
  vtkSmartPointer<vtkPolyDataAlgorithm> reader;
  if (ext == ".stl") {
    auto r = vtkSmartPointer<vtkSTLReader>::New();
    r->SetFileName(path.string().c_str());
    r->MergingOff();  // vtkCleanPolyData merges below
    reader = r;
  } else if (ext == ".obj") {
    auto r = vtkSmartPointer<vtkOBJReader>::New();
    r->SetFileName(path.string().c_str());
    reader = r;
  } else if (ext == ".ply") {
    auto r = vtkSmartPointer<vtkPLYReader>::New();
    r->SetFileName(path.string().c_str());
    reader = r;
  } else {
    fail(path, "unsupported mesh format \"" + ext + "\" (expected .stl, .obj or .ply)");
  }

  detail::VtkErrorCapture capture;
  capture.watch(reader);
  auto triangles = vtkSmartPointer<vtkTriangleFilter>::New();
  capture.watch(triangles);
  triangles->SetInputConnection(reader->GetOutputPort());
  triangles->PassVertsOff();
  triangles->PassLinesOff();
  auto clean = vtkSmartPointer<vtkCleanPolyData>::New();
  capture.watch(clean);
  clean->SetInputConnection(triangles->GetOutputPort());
  clean->PointMergingOn();
  clean->SetTolerance(0.0);  // merge exactly coincident points (STL repeats every vertex)
  clean->ConvertPolysToLinesOff();
  clean->ConvertLinesToPointsOff();
  clean->Update();
  if (capture.hasErrors()) fail(path, "cannot be read as a mesh: " + capture.firstError());

  vtkPolyData* poly = clean->GetOutput();
  haptics::TriangleMesh mesh;
  vtkPoints* points = poly != nullptr ? poly->GetPoints() : nullptr;
  vtkCellArray* polys = poly != nullptr ? poly->GetPolys() : nullptr;
  if (points == nullptr || polys == nullptr || polys->GetNumberOfCells() == 0) {
    fail(path, "no triangles found (not a mesh, or an empty one)");
  }
  mesh.vertices_T_m.reserve(static_cast<std::size_t>(points->GetNumberOfPoints()));
  for (vtkIdType i = 0; i < points->GetNumberOfPoints(); ++i) {
    double p[3];
    points->GetPoint(i, p);
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      fail(path, "vertex " + std::to_string(i) + " has a non-finite coordinate");
    }
    mesh.vertices_T_m.emplace_back(scale_to_m * p[0], scale_to_m * p[1], scale_to_m * p[2]);
  }
  mesh.triangles.reserve(static_cast<std::size_t>(polys->GetNumberOfCells()));
  auto ids = vtkSmartPointer<vtkIdList>::New();
  for (polys->InitTraversal(); polys->GetNextCell(ids) != 0;) {
    if (ids->GetNumberOfIds() != 3) continue;  // the triangle filter leaves only triangles
    const std::array<int, 3> t{static_cast<int>(ids->GetId(0)), static_cast<int>(ids->GetId(1)),
                               static_cast<int>(ids->GetId(2))};
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    mesh.triangles.push_back(t);
  }
  if (mesh.triangles.empty()) fail(path, "no triangles found (only degenerate faces)");
  return mesh;
}

}  // namespace vh::io
