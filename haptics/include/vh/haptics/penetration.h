#pragma once
/// @file
/// How deep a posed point shell is inside the isosurface: the measure the proxy must keep below
/// epsilon (paper section 2.3), used by tests, the headless runner's report and benchmarks.

#include "vh/haptics/point_shell.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"

namespace vh::haptics {

/// Largest depth [m] of any point of `shell` at pose X_WT inside the isosurface F = isovalue,
/// each estimated to first order as (F(p) - s) / |grad F(p)| (eq. 1 gradient); a point inside
/// where the gradient vanishes counts one voxel diagonal. 0 when no point is inside.
/// @param deepest_point when not null, receives the index of the deepest point (-1 if none).
/// Allocation free; O(n) samples plus a gradient per inside point.
double maxPenetration_m(const ScalarVolume& volume, const PointShell& shell, const Pose& X_WT, double isovalue,
                        int* deepest_point = nullptr) noexcept;

}  // namespace vh::haptics
