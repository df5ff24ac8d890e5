#pragma once
/// @file
/// NIfTI-1 and NIfTI-2 reading (nifti_loader.cpp), for the format dispatch of loadVolume() and
/// the segmentation reader. Private to vh::io.

#include <filesystem>
#include <string_view>

#include "vh/io/volume_loader.h"

namespace vh::io::detail {

/// A NIfTI-1 or NIfTI-2 file (.nii, .nii.gz, or the .hdr or .img of a pair) read in this
/// process: placed by the sform when sform_code > 0 (a sheared sform gives way to the qform when
/// there is one), else the qform when qform_code > 0, else pixdim alone (the NIfTI-1 standard's
/// method 1); RAS+ in the unit of xyzt_units converted to patient LPS [m]; scl_slope / scl_inter
/// become the field's value scale and offset; a 4-D file's first volume, with a notice.
/// @throws LoadError naming `path` for a damaged header (short, bad sizeof_hdr or magic, an
///         Analyze 7.5 header, dimensions 0, negative or absurd, an unknown or non-scalar
///         datatype), voxel data shorter than announced, or a reader error.
LoadedVolume loadNifti(const std::filesystem::path& path);

/// True when the name is a NIfTI one: .nii, .nii.gz, .hdr(.gz), or .img(.gz) beside a .hdr.
bool isNiftiFileName(const std::filesystem::path& path);

/// True when `head` (a file's first bytes, uncompressed) holds a NIfTI-1 or NIfTI-2 magic.
bool hasNiftiMagic(std::string_view head);

/// True when `path` is a NIfTI whose intent_code is NIFTI_INTENT_LABEL (the values are labels).
/// Never throws (false when unreadable).
bool isNiftiLabelMap(const std::filesystem::path& path);

}  // namespace vh::io::detail
