#pragma once
// For drilling tests: a CT scan of a ball whose HU classes and partial volume are known at every
// voxel (so that what a burr removed can be classed from the scan alone), and a straight press.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include <Eigen/Core>

#include "vh/runtime/trajectory.h"

namespace vh::test {

/// The device (its orientation the identity) straight down at (x, y) [m] in W from z_from to
/// z_to [m] over the first t_down_s seconds, then held there until t_end_s [s].
inline runtime::Trajectory pressTrajectory(double x, double y, double z_from, double t_down_s, double z_to,
                                           double t_end_s) {
  const auto at = [&](double t, double z) {
    runtime::TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = {x, y, z};
    return s;
  };
  return runtime::Trajectory({at(0.0, z_from), at(t_down_s, z_to), at(t_end_s, z_to)});
}

/// Writes a MetaImage CT (int16 HU, 1 mm voxels, 48^3, the grid centred on the origin) of a
/// ball of radius 20 mm about the origin, 1000 HU inside, -1000 HU outside, linear over 2 mm
/// across its surface (a scan's partial volume), and a scene file that drills it with the
/// built-in drill (burr radius 2.5 mm, on from the start, coupling 400 N/m).
/// @return the scene file, `dir`/ball-ct.json (the scan beside it, ball-ct.mha).
inline std::filesystem::path writeCtBallScene(const std::filesystem::path& dir) {
  constexpr int kN = 48;
  constexpr double kCentre = 0.5 * (kN - 1);  // voxel index of the origin
  {
    std::ofstream mha(dir / "ball-ct.mha", std::ios::binary);
    const std::string n = std::to_string(kN), o = std::to_string(-kCentre);
    mha << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
        << "DimSize = " << n << " " << n << " " << n << "\nElementSpacing = 1 1 1\n"
        << "Offset = " << o << " " << o << " " << o << "\nModality = MET_MOD_CT\n"
        << "ElementType = MET_SHORT\nElementDataFile = LOCAL\n";
    for (int k = 0; k < kN; ++k)
      for (int j = 0; j < kN; ++j)
        for (int i = 0; i < kN; ++i) {
          const double r_mm = Eigen::Vector3d(i - kCentre, j - kCentre, k - kCentre).norm();
          const auto hu = static_cast<std::int16_t>(std::lround(std::clamp(1000.0 * (20.0 - r_mm), -1000.0, 1000.0)));
          mha.write(reinterpret_cast<const char*>(&hu), sizeof hu);
        }
  }
  std::ofstream(dir / "ball-ct.json") << R"({
    "volume": {"path": "ball-ct.mha"},
    "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
    "coupling": {"linear_N_per_m": 400},
    "drill": {"on": true, "burr_radius_m": 0.0025}
  })";
  return dir / "ball-ct.json";
}

}  // namespace vh::test
