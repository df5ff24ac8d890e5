#include "vh/datasets/synthetic.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace vh::datasets {
namespace {

using haptics::ScalarVolume;
using haptics::TriangleMesh;
using haptics::VolumeGeometry;

VolumeGeometry geometryOf(const GridSpec& grid) {
  VolumeGeometry g;
  g.dims = grid.dims;
  g.spacing_m = grid.spacing_m;
  if (grid.origin_W_m.allFinite()) {
    g.origin_W_m = grid.origin_W_m;
  } else {
    for (int a = 0; a < 3; ++a) g.origin_W_m[a] = -0.5 * (grid.dims[a] - 1) * grid.spacing_m[a];
  }
  return g;
}

// Fills a float32 grid with f(p_W).
ScalarVolume fromFunction(const GridSpec& grid, const std::function<double(const Eigen::Vector3d&)>& f) {
  const VolumeGeometry g = geometryOf(grid);
  std::vector<float> voxels(g.voxelCount());
  std::size_t idx = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + Eigen::Vector3d(i * g.spacing_m[0], j * g.spacing_m[1], k * g.spacing_m[2]);
        voxels[idx++] = static_cast<float>(f(p));
      }
  return ScalarVolume::FromVoxels(g, voxels);
}

}  // namespace

ScalarVolume makeVolumeFromSignedDistance(const GridSpec& grid, const SignedDistance& solid, haptics::VoxelType type) {
  const VolumeGeometry g = geometryOf(grid);
  const std::size_t n = g.voxelCount();
  const double h_mm = 1000.0 * g.spacing_m.minCoeff();
  auto at = [&](std::size_t idx) {
    const int i = static_cast<int>(idx % g.dims[0]);
    const int j = static_cast<int>((idx / g.dims[0]) % g.dims[1]);
    const int k = static_cast<int>(idx / (static_cast<std::size_t>(g.dims[0]) * g.dims[1]));
    return 1000.0 * solid(g.origin_W_m + Eigen::Vector3d(i * g.spacing_m[0], j * g.spacing_m[1], k * g.spacing_m[2]));
  };
  switch (type) {
    case haptics::VoxelType::kFloat32: {
      std::vector<float> v(n);
      for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<float>(at(i));
      return ScalarVolume::FromVoxels(g, v);
    }
    case haptics::VoxelType::kInt16: {
      std::vector<std::int16_t> v(n);
      for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<std::int16_t>(std::clamp(std::lround(100.0 * at(i)), -32767L, 32767L));
      return ScalarVolume::FromVoxels(g, v, 0.01, 0.0);
    }
    case haptics::VoxelType::kUInt16: {
      std::vector<std::uint16_t> v(n);
      for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<std::uint16_t>(std::clamp(std::lround(100.0 * at(i)) + 32768L, 0L, 65535L));
      return ScalarVolume::FromVoxels(g, v, 0.01, -327.68);
    }
    case haptics::VoxelType::kUInt8: {
      std::vector<std::uint8_t> v(n);
      for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<std::uint8_t>(std::clamp(std::lround(128.0 + 50.0 * at(i) / h_mm), 0L, 255L));
      return ScalarVolume::FromVoxels(g, v, h_mm / 50.0, -128.0 * h_mm / 50.0);
    }
  }
  throw std::invalid_argument("makeVolumeFromSignedDistance: unknown voxel type");
}

ScalarVolume makePlaneVolume(const GridSpec& grid, const Eigen::Vector3d& normal_W, double offset_m) {
  if (!(normal_W.norm() > 0.0)) throw std::invalid_argument("makePlaneVolume: zero normal");
  const Eigen::Vector3d n = normal_W.normalized();
  return fromFunction(grid, [&](const Eigen::Vector3d& p) { return 1000.0 * (offset_m - n.dot(p)); });
}

ScalarVolume makeSphereVolume(const GridSpec& grid, const Eigen::Vector3d& centre_W_m, double radius_m) {
  return fromFunction(grid, [&](const Eigen::Vector3d& p) { return 1000.0 * (radius_m - (p - centre_W_m).norm()); });
}

ScalarVolume makeThinPlateVolume(const GridSpec& grid) {
  const VolumeGeometry g = geometryOf(grid);
  std::vector<std::uint8_t> voxels(g.voxelCount(), 0);
  const int k = g.dims[2] / 2;
  const std::size_t slice = static_cast<std::size_t>(g.dims[0]) * g.dims[1];
  std::fill_n(voxels.begin() + static_cast<std::ptrdiff_t>(slice * k), slice, std::uint8_t{255});
  return ScalarVolume::FromVoxels(g, voxels);
}

ScalarVolume makeThinWallVolume(const GridSpec& grid, const SignedDistance& mid_surface) {
  const VolumeGeometry g = geometryOf(grid);
  const double h = g.spacing_m.minCoeff();
  std::vector<std::uint8_t> voxels(g.voxelCount());
  std::size_t idx = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + Eigen::Vector3d(i * g.spacing_m[0], j * g.spacing_m[1], k * g.spacing_m[2]);
        const double w = std::max(0.0, 1.0 - std::abs(mid_surface(p)) / h);
        voxels[idx++] = static_cast<std::uint8_t>(std::lround(255.0 * w));
      }
  return ScalarVolume::FromVoxels(g, voxels);
}

ScalarVolume makeThinShellVolume(const GridSpec& grid, const Eigen::Vector3d& centre_W_m, double radius_m) {
  return makeThinWallVolume(grid, [&](const Eigen::Vector3d& p) { return (p - centre_W_m).norm() - radius_m; });
}

ScalarVolume makeThinTubeVolume(const GridSpec& grid, double radius_m) {
  return makeThinWallVolume(grid, [&](const Eigen::Vector3d& p) { return std::hypot(p.x(), p.y()) - radius_m; });
}

ScalarVolume makeBlockWithHoleVolume(int dims) { return makeBlockWithBlindHoleVolume(dims, -1.0); }

ScalarVolume makeBlockWithBlindHoleVolume(int dims, double hole_bottom_z_m) {
  if (dims < 16) throw std::invalid_argument("makeBlockWithHoleVolume: dims < 16");
  GridSpec grid;
  const double spacing = 0.064 / dims;
  grid.dims = {dims, dims, dims};
  grid.spacing_m = Eigen::Vector3d::Constant(spacing);
  const VolumeGeometry g = geometryOf(grid);
  std::vector<std::uint8_t> voxels(g.voxelCount());
  const Eigen::Vector3d half(0.024, 0.024, kBlockHalfHeight_m);
  std::size_t idx = 0;
  for (int k = 0; k < dims; ++k)
    for (int j = 0; j < dims; ++j)
      for (int i = 0; i < dims; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + spacing * Eigen::Vector3d(i, j, k);
        // Signed distance (positive inside) of the box, and of the outside of the hole.
        const Eigen::Vector3d q = half - p.cwiseAbs();
        const double d_box = q.minCoeff() >= 0.0 ? q.minCoeff() : -q.cwiseMin(0.0).norm();
        // Outside the hole: radial distance beyond the wall, or depth below a blind hole's floor.
        const double d_radial = std::hypot(p.x(), p.y()) - kHoleRadius_m;
        const double d_hole = std::max(d_radial, hole_bottom_z_m - p.z());
        const double d = std::min(d_box, d_hole);
        const double v = std::clamp(128.0 + 50.0 * d / spacing, 0.0, 255.0);
        voxels[idx++] = static_cast<std::uint8_t>(std::lround(v));
      }
  return ScalarVolume::FromVoxels(g, voxels);
}

TriangleMesh makeCylinderMesh(double radius_m, double length_m, int segments) {
  if (!(radius_m > 0) || !(length_m > 0) || segments < 3) throw std::invalid_argument("makeCylinderMesh: bad size");
  TriangleMesh m;
  for (int z = 0; z < 2; ++z)
    for (int s = 0; s < segments; ++s) {
      const double a = 2.0 * std::numbers::pi * s / segments;
      m.vertices_T_m.emplace_back(radius_m * std::cos(a), radius_m * std::sin(a), z * length_m);
    }
  const int bottom = static_cast<int>(m.vertices_T_m.size());
  m.vertices_T_m.emplace_back(0, 0, 0);
  const int top = bottom + 1;
  m.vertices_T_m.emplace_back(0, 0, length_m);
  for (int s = 0; s < segments; ++s) {
    const int s1 = (s + 1) % segments;
    m.triangles.push_back({s, s1, segments + s1});
    m.triangles.push_back({s, segments + s1, segments + s});
    m.triangles.push_back({bottom, s1, s});
    m.triangles.push_back({top, segments + s, segments + s1});
  }
  return m;
}

TriangleMesh makeSphereMesh(double radius_m, int subdivisions) {
  if (!(radius_m > 0)) throw std::invalid_argument("makeSphereMesh: bad radius");
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.vertices_T_m = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                    {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  m.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (auto& v : m.vertices_T_m) v.normalize();
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      m.vertices_T_m.push_back((m.vertices_T_m[a] + m.vertices_T_m[b]).normalized());
      const int id = static_cast<int>(m.vertices_T_m.size()) - 1;
      midpoint.emplace(key, id);
      return id;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& tri : m.triangles) {
      const int a = mid(tri[0], tri[1]), b = mid(tri[1], tri[2]), c = mid(tri[2], tri[0]);
      next.push_back({tri[0], a, c});
      next.push_back({tri[1], b, a});
      next.push_back({tri[2], c, b});
      next.push_back({a, b, c});
    }
    m.triangles = std::move(next);
  }
  for (auto& v : m.vertices_T_m) v *= radius_m;
  return m;
}

TriangleMesh makeBoxMesh(const Eigen::Vector3d& h) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i)
    m.vertices_T_m.emplace_back((i & 1 ? 1 : -1) * h.x(), (i & 2 ? 1 : -1) * h.y(), (i & 4 ? 1 : -1) * h.z());
  m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return m;
}

TriangleMesh concatenate(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh m = a;
  const int base = static_cast<int>(a.vertices_T_m.size());
  m.vertices_T_m.insert(m.vertices_T_m.end(), b.vertices_T_m.begin(), b.vertices_T_m.end());
  for (const auto& t : b.triangles) m.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  return m;
}

TriangleMesh translated(TriangleMesh mesh, const Eigen::Vector3d& d_T_m) {
  for (auto& v : mesh.vertices_T_m) v += d_T_m;
  return mesh;
}

TriangleMesh makeBuiltinTool(const std::string& name) {
  if (name == "peg") return makeCylinderMesh(kPegRadius_m, 0.040, 64);
  if (name == "probe")
    return concatenate(makeSphereMesh(0.002, 2), makeCylinderMesh(0.001, 0.060, 16));
  if (name == "drill")
    return concatenate(concatenate(makeSphereMesh(0.0025, 2), makeCylinderMesh(0.0012, 0.030, 16)),
                       translated(makeCylinderMesh(0.005, 0.060, 32), Eigen::Vector3d(0, 0, 0.030)));
  if (name == "sphere") return makeSphereMesh(0.005, 3);
  throw std::invalid_argument("unknown built-in tool '" + name + "' (peg, probe, drill, sphere)");
}

ScalarVolume makeGelWithInclusionVolume() {
  GridSpec grid;
  grid.dims = {48, 48, 40};
  grid.spacing_m = Eigen::Vector3d::Constant(0.5e-3);
  grid.origin_W_m = Eigen::Vector3d(-11.75e-3, -11.75e-3, 0.0);
  const VolumeGeometry g = geometryOf(grid);
  std::vector<float> voxels(g.voxelCount());
  std::size_t idx = 0;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i, ++idx) {
        const Eigen::Vector3d p = g.origin_W_m + grid.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        double v = std::clamp(kGelValue / 2.0 + kGelValue / 2.0 * (kGelTop_m - p.z()) / 1e-3, 0.0, kGelValue);
        if ((p - kGelInclusionCentre_m).norm() < kGelInclusionRadius_m) v = 2.0 * kGelValue;
        if (p.z() < kGelPlate_m) v = 1000.0;  // the bone plate it lies on
        voxels[idx] = static_cast<float>(v);
      }
  return ScalarVolume::FromVoxels(g, voxels);
}

ScalarVolume makeBuiltinVolume(const std::string& name) {
  GridSpec grid;  // 64^3 of 1 mm centred on the origin
  if (name == "block-with-hole") return makeBlockWithHoleVolume(256);
  if (name == "gel-with-inclusion") return makeGelWithInclusionVolume();
  if (name == "plane") return makePlaneVolume(grid, Eigen::Vector3d::UnitZ(), 0.0);
  if (name == "sphere") return makeSphereVolume(grid, Eigen::Vector3d::Zero(), 0.020);
  if (name == "thin-plate") return makeThinPlateVolume(grid);
  if (name == "thin-shell") return makeThinShellVolume(grid, Eigen::Vector3d::Zero(), 0.020);
  if (name == "thin-tube") return makeThinTubeVolume(grid, 0.015);
  throw std::invalid_argument("unknown built-in volume '" + name +
                              "' (block-with-hole, gel-with-inclusion, plane, sphere, thin-plate, thin-shell, thin-tube)");
}

double builtinIsovalue(const std::string& name) {
  if (name == "block-with-hole") return kBlockIsovalue;
  if (name == "gel-with-inclusion") return kGelValue / 2.0;
  if (name == "thin-plate" || name == "thin-shell" || name == "thin-tube") return 127.5;
  if (name == "plane" || name == "sphere") return 0.0;
  throw std::invalid_argument("unknown built-in volume '" + name + "'");
}

}  // namespace vh::datasets
