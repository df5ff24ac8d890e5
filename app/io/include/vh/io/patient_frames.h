#pragma once
/// @file
/// The patient coordinate frames of scans, and the one conversion between them.
///
///  - LPS: DICOM's patient frame: +x towards the patient's Left, +y Posterior, +z Superior. The
///    scene frame W is LPS for scans (io::loadVolume(), in metres).
///  - RAS: the patient frame of 3D Slicer, OpenIGTLink and NIfTI: +x Right, +y Anterior,
///    +z Superior.
///  - LAS: +x Left, +y Anterior, +z Superior (a NRRD `space`).
///
/// LPS and RAS differ by a half turn about the superior axis: p_RAS = F p_LPS with
/// F = diag(-1, -1, 1), and F is its own inverse, so p_LPS = F p_RAS. A rotation or direction
/// matrix R_LPS (columns = axes in LPS) is R_RAS = F R_LPS F. The flips change no length:
/// points and vectors keep their unit (mm stay mm, N stay N).

#include <Eigen/Core>

namespace vh::io {

/// F = diag(-1, -1, 1), the 3 x 3 sign flip taking LPS coordinates to RAS (F = F^-1 = F^T).
inline Eigen::Matrix3d rasFromLpsMatrix() { return Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal(); }

/// F = diag(-1, -1, 1), the 3 x 3 sign flip taking RAS coordinates to LPS (the same matrix as
/// rasFromLpsMatrix()).
inline Eigen::Matrix3d lpsFromRasMatrix() { return rasFromLpsMatrix(); }

/// A point or vector given in LPS, expressed in RAS: (-x, -y, z), same unit.
inline Eigen::Vector3d rasFromLps(const Eigen::Vector3d& v_LPS) { return {-v_LPS.x(), -v_LPS.y(), v_LPS.z()}; }

/// A point or vector given in RAS, expressed in LPS: (-x, -y, z), same unit.
inline Eigen::Vector3d lpsFromRas(const Eigen::Vector3d& v_RAS) { return {-v_RAS.x(), -v_RAS.y(), v_RAS.z()}; }

/// diag(1, -1, 1), the 3 x 3 sign flip taking LAS coordinates to LPS (and back).
inline Eigen::Matrix3d lpsFromLasMatrix() { return Eigen::Vector3d(1.0, -1.0, 1.0).asDiagonal(); }

}  // namespace vh::io
