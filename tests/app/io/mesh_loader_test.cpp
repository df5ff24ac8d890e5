// Tool meshes: the real STL / OBJ files and synthetic PLY / OBJ written here.
#include <chrono>
#include <iostream>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <vtkCubeSource.h>
#include <vtkPLYWriter.h>
#include <vtkSmartPointer.h>

#include "io_test_support.h"
#include "vh/io/volume_loader.h"

namespace {

namespace fs = std::filesystem;
using vh::haptics::TriangleMesh;
using vh::io::loadMesh;
using vh::io::test::secondsSince;
using vh::io::test::TempDir;
using vh::io::test::writeFile;

Eigen::Vector3d extent(const TriangleMesh& m) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300);
  Eigen::Vector3d hi = -lo;
  for (const auto& p : m.vertices_T_m) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return hi - lo;
}

double area(const TriangleMesh& m) {
  double a = 0.0;
  for (const auto& t : m.triangles) {
    const auto& p0 = m.vertices_T_m[static_cast<std::size_t>(t[0])];
    const auto& p1 = m.vertices_T_m[static_cast<std::size_t>(t[1])];
    const auto& p2 = m.vertices_T_m[static_cast<std::size_t>(t[2])];
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

double signedVolume(const TriangleMesh& m) {
  double v = 0.0;
  for (const auto& t : m.triangles) {
    v += m.vertices_T_m[static_cast<std::size_t>(t[0])].dot(
             m.vertices_T_m[static_cast<std::size_t>(t[1])].cross(
                 m.vertices_T_m[static_cast<std::size_t>(t[2])])) /
         6.0;
  }
  return v;
}

void expectValidIndices(const TriangleMesh& m) {
  const int n = static_cast<int>(m.vertices_T_m.size());
  for (const auto& t : m.triangles) {
    for (int i : t) {
      ASSERT_GE(i, 0);
      ASSERT_LT(i, n);
    }
  }
}

TEST(MeshLoad, DrillStl) {
  VH_REQUIRE_SHARED(file, "meshes/drill/drill.stl");
  const auto t0 = std::chrono::steady_clock::now();
  const TriangleMesh unit = loadMesh(file);
  std::cout << "[timing] drill.stl: " << secondsSince(t0) << " s\n";
  EXPECT_GE(unit.triangles.size(), 850u);
  EXPECT_LE(unit.triangles.size(), 886u);
  // STL repeats every vertex per triangle; merged, far fewer remain.
  EXPECT_LT(unit.vertices_T_m.size(), unit.triangles.size());
  expectValidIndices(unit);
  const double length = extent(unit).maxCoeff();
  EXPECT_NEAR(length, 227.0, 5.0);
  const TriangleMesh scaled = loadMesh(file, 0.1 / length);
  EXPECT_NEAR(extent(scaled).maxCoeff(), 0.1, 1e-9);
  EXPECT_EQ(scaled.triangles, unit.triangles);
}

TEST(MeshLoad, DentalInstrumentObj) {
  VH_REQUIRE_SHARED(file, "meshes/dental-probe/dental_instrument.obj");
  const auto t0 = std::chrono::steady_clock::now();
  const TriangleMesh m = loadMesh(file, 1e-3);
  std::cout << "[timing] dental_instrument.obj: " << secondsSince(t0) << " s\n";
  EXPECT_GE(m.triangles.size(), 2100u);
  EXPECT_LE(m.triangles.size(), 2178u);
  expectValidIndices(m);
  EXPECT_GT(area(m), 0.0);
}

TEST(MeshLoad, PegInHoleObjInMetres) {
  VH_REQUIRE_SHARED(file, "meshes/peg-in-hole/factory_round_peg_16mm_tight.obj");
  const TriangleMesh m = loadMesh(file);
  expectValidIndices(m);
  const Eigen::Vector3d e = extent(m);
  // A 16 mm peg, in metres: its diameter is 16 mm.
  EXPECT_NEAR(std::min({e.x(), e.y(), e.z()}), 0.016, 0.002);
}

TEST(MeshLoad, WrenchStl) {
  VH_REQUIRE_SHARED(file, "meshes/wrench/adjustable-wrench-body.stl");
  const auto t0 = std::chrono::steady_clock::now();
  const TriangleMesh m = loadMesh(file, 1e-3);
  std::cout << "[timing] adjustable-wrench-body.stl: " << secondsSince(t0) << " s\n";
  EXPECT_GT(m.triangles.size(), 15000u);
  EXPECT_NEAR(extent(m).maxCoeff(), 0.150, 0.005);
}

TEST(MeshLoad, PlyCubeWrittenHere) {
  TempDir tmp("ply_cube");
  auto cube = vtkSmartPointer<vtkCubeSource>::New();
  cube->SetXLength(10);
  cube->SetYLength(10);
  cube->SetZLength(10);
  auto writer = vtkSmartPointer<vtkPLYWriter>::New();
  writer->SetInputConnection(cube->GetOutputPort());
  writer->SetFileName((tmp / "cube.ply").string().c_str());
  writer->Write();
  const TriangleMesh m = loadMesh(tmp / "cube.ply", 1e-3);
  EXPECT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(m.vertices_T_m.size(), 8u);  // 24 source points merged
  expectValidIndices(m);
  EXPECT_NEAR(area(m), 6 * 0.01 * 0.01, 1e-12);
  EXPECT_NEAR(signedVolume(m), 1e-6, 1e-12);  // outward orientation kept
}

TEST(MeshLoad, ObjQuadIsTriangulated) {
  TempDir tmp("obj_quad");
  writeFile(tmp / "quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  const TriangleMesh m = loadMesh(tmp / "quad.obj", 2.0);
  EXPECT_EQ(m.triangles.size(), 2u);
  EXPECT_NEAR(area(m), 4.0, 1e-12);
}

}  // namespace
