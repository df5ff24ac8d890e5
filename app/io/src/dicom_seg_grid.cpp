// DICOM SEG frames on a grid (dicom_seg.h): the scan's grid or the one the frames span, each
// frame's geometry checked against it, the overlapping segments' label layers, and the
// LoadedSegmentation, the same as a layered .seg.nrrd gives.
//
// A frame's pixel (column c, row r) lies at p = IPP + c dc row_dir + r dr col_dir (PS3.3
// C.7.6.2.1.1: Image Position (Patient) is the centre of the first pixel, Image Orientation
// (Patient) the row and column directions, Pixel Spacing = dr \ dc), LPS in mm. A grid voxel
// (i, j, k) lies at origin + D diag(spacing) (i, j, k) in W = LPS in m, D's columns the i, j, k
// axes (haptics::VolumeGeometry). The DICOM loader makes D = (row_dir, col_dir, normal) and i the
// column (dicom_loader.cpp), so a frame of the scan's series has i = c, j = r and k = the
// frame's position along the slice axis: (D^T (IPP - origin))_k / spacing_k.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "dicom_seg_internal.h"
#include "loader_internal.h"
#include "vh/io/dicom_seg.h"

namespace vh::io {

std::pair<std::size_t, int> detail::SegmentLayers::take(
    const std::function<bool(const std::vector<std::uint8_t>& layer)>& fits) {
  std::size_t l = 0;
  while (l < voxels.size() && (used[l] >= kLabelsPerLayer || !fits(voxels[l]))) ++l;
  if (l == voxels.size()) {
    voxels.emplace_back(voxel_count, 0);
    used.push_back(0);
  }
  return {l, ++used[l]};
}

namespace {

namespace fs = std::filesystem;
using detail::DicomSegFile;
using detail::DicomSegFrame;
using detail::SegmentLayers;
using detail::fail;

/// A frame within this fraction of a voxel of a grid position is on it (DICOM writes positions
/// as decimal strings; a frame a tenth of a voxel off belongs to another grid).
constexpr double kOnGridVoxels = 0.1;
/// Directions agree when their cosine is within this of 1 (about 2.6 deg).
constexpr double kDirectionCosine = 1e-3;
/// Spacings agree within this fraction.
constexpr double kSpacingFraction = 1e-3;
/// Labels per layer (the layers are uint8).

std::string num(double v, int decimals = 3) {
  char s[64];
  std::snprintf(s, sizeof(s), "%.*f", decimals, v);
  return s;
}

std::string vec(const Eigen::Vector3d& v, int decimals = 3) {
  char s[160];
  std::snprintf(s, sizeof(s), "(%.*f, %.*f, %.*f)", decimals, v.x(), decimals, v.y(), decimals, v.z());
  return s;
}

std::string frameName(std::size_t f, const DicomSegFrame& frame) {
  return "frame " + std::to_string(f + 1) + " (segment " + std::to_string(frame.segment) + ")";
}

/// The slice index of each frame on `g`, after checking that the frame is one of g's slices:
/// the same rows and columns, orientation, pixel spacing and in-plane position, and a position
/// along the slice axis on one of g's slices. `grid` names g in messages ("the scan").
std::vector<int> sliceIndices(const DicomSegFile& file, const haptics::VolumeGeometry& g, const fs::path& path,
                              const std::string& grid) {
  if (file.columns != g.dims[0] || file.rows != g.dims[1]) {
    fail(path, "its frames are " + std::to_string(file.columns) + " x " + std::to_string(file.rows) +
                   " pixels (columns x rows), " + grid + "'s slices " + std::to_string(g.dims[0]) + " x " +
                   std::to_string(g.dims[1]) + ": not a segmentation of " + grid);
  }
  const Eigen::Vector3d spacing_mm = g.spacing_m * 1e3;
  std::vector<int> k_of(file.frames.size());
  for (std::size_t f = 0; f < file.frames.size(); ++f) {
    const DicomSegFrame& fr = file.frames[f];
    if (fr.row_dir.dot(g.direction_W.col(0)) < 1.0 - kDirectionCosine ||
        fr.col_dir.dot(g.direction_W.col(1)) < 1.0 - kDirectionCosine) {
      fail(path, frameName(f, fr) + ": its orientation (rows along " + vec(fr.row_dir, 4) + ", columns along " +
                     vec(fr.col_dir, 4) + ", Image Orientation (Patient)) is not " + grid + "'s (" +
                     vec(g.direction_W.col(0), 4) + ", " + vec(g.direction_W.col(1), 4) + ")");
    }
    if (std::abs(fr.column_spacing_mm - spacing_mm.x()) > kSpacingFraction * spacing_mm.x() ||
        std::abs(fr.row_spacing_mm - spacing_mm.y()) > kSpacingFraction * spacing_mm.y()) {
      fail(path, frameName(f, fr) + ": its pixel spacing " + num(fr.row_spacing_mm, 4) + " x " +
                     num(fr.column_spacing_mm, 4) + " mm (Pixel Spacing, rows \\ columns) is not " + grid + "'s " +
                     num(spacing_mm.y(), 4) + " x " + num(spacing_mm.x(), 4) + " mm");
    }
    // The frame's first pixel in g's voxel coordinates.
    const Eigen::Vector3d u =
        (g.direction_W.transpose() * (fr.position_mm * 1e-3 - g.origin_W_m)).cwiseQuotient(g.spacing_m);
    if (std::abs(u.x()) > kOnGridVoxels || std::abs(u.y()) > kOnGridVoxels) {
      fail(path, frameName(f, fr) + ": its Image Position (Patient) " + vec(fr.position_mm) + " mm is " +
                     num(u.x(), 2) + " columns and " + num(u.y(), 2) + " rows off " + grid + "'s first pixel: not on " +
                     grid + "'s grid");
    }
    const double k = std::round(u.z());
    if (std::abs(u.z() - k) > kOnGridVoxels) {
      fail(path, frameName(f, fr) + ": its Image Position (Patient) " + vec(fr.position_mm) +
                     " mm lies between slices of " + grid + " (slice index " + num(u.z(), 2) + "): off " + grid +
                     "'s slice grid (another slice spacing or a shifted position)");
    }
    if (k < 0.0 || k >= g.dims[2]) {
      fail(path, frameName(f, fr) + ": its Image Position (Patient) " + vec(fr.position_mm) + " mm lies outside " +
                     grid + " (slice index " + num(k, 0) + " of 0.." + std::to_string(g.dims[2] - 1) + ")");
    }
    k_of[f] = static_cast<int>(k);
  }
  return k_of;
}

/// The grid the frames span, for a SEG opened without a scan: the lowest frame's plane axes and
/// pixel spacing, slices from the lowest frame to the highest along the normal at the Spacing
/// Between Slices (else the Slice Thickness when every gap is a whole number of it, else the
/// smallest gap), at least two slices (a ScalarVolume needs two on every axis).
haptics::VolumeGeometry ownGrid(const DicomSegFile& file, const fs::path& path, std::vector<std::string>& notices) {
  if (file.rows < 2 || file.columns < 2) fail(path, "its frames of one row or one column are not a volume");
  const Eigen::Vector3d normal = file.frames.front().row_dir.cross(file.frames.front().col_dir).normalized();
  std::vector<double> d;
  std::size_t lowest = 0;
  for (std::size_t f = 0; f < file.frames.size(); ++f) {
    d.push_back(file.frames[f].position_mm.dot(normal));
    if (d.back() < d[lowest]) lowest = f;
  }
  const DicomSegFrame& first = file.frames[lowest];
  haptics::VolumeGeometry g;
  g.direction_W.col(0) = first.row_dir;
  g.direction_W.col(2) = first.row_dir.cross(first.col_dir).normalized();
  g.direction_W.col(1) = g.direction_W.col(2).cross(g.direction_W.col(0));  // exactly orthonormal
  std::sort(d.begin(), d.end());
  double gap = 0.0;  // smallest gap between distinct planes
  bool thickness_fits = file.slice_thickness_mm > 0.0;
  for (std::size_t n = 1; n < d.size(); ++n) {
    const double step = d[n] - d[n - 1];
    if (step < 1e-3) continue;
    gap = gap == 0.0 ? step : std::min(gap, step);
    if (thickness_fits) {
      const double m = step / file.slice_thickness_mm;
      thickness_fits = std::abs(m - std::round(m)) <= kOnGridVoxels;
    }
  }
  double step = file.spacing_between_slices_mm;
  if (!(step > 0.0)) step = thickness_fits ? file.slice_thickness_mm : gap;
  if (!(step > 0.0)) step = std::min(first.row_spacing_mm, first.column_spacing_mm);  // one plane
  const double slices = (d.back() - d.front()) / step + 1.0;
  if (!(slices * file.rows * file.columns < 2e9)) {  // a layer must stay allocatable (uint8)
    fail(path, "its frames span " + num(d.back() - d.front(), 1) + " mm in steps of " + num(step) +
                   " mm: too many voxels for one volume");
  }
  g.dims = {file.columns, file.rows, std::max(2, static_cast<int>(std::lround(slices)))};
  g.spacing_m = Eigen::Vector3d(first.column_spacing_mm, first.row_spacing_mm, step) * 1e-3;
  g.origin_W_m = file.frames[lowest].position_mm * 1e-3;
  notices.push_back("opened without a scan: on the grid its frames span (" + std::to_string(g.dims[2]) + " slices of " +
                    num(step) + " mm); open it on the scan to place it on the scan's voxels and check its references");
  return g;
}

/// The scan's DICOM UIDs against the SEG's references: the scan's series must be one the SEG
/// references and its frame of reference the SEG's. A scan without UIDs is matched by position
/// only (a notice says so).
void checkReferences(const DicomSegFile& file, const VolumeInfo& scan, const fs::path& path,
                     std::vector<std::string>& notices) {
  if (scan.series_uid.empty()) {
    notices.push_back("the scan has no DICOM Series Instance UID (" +
                      (scan.format.empty() ? "not DICOM" : scan.format) +
                      "), so the SEG's references were not checked: placed by its patient coordinates only");
  } else if (file.referenced_series_uids.empty()) {
    notices.push_back(
        "the SEG names no referenced series (Referenced Series Sequence): placed by its patient "
        "coordinates only");
  } else if (std::find(file.referenced_series_uids.begin(), file.referenced_series_uids.end(), scan.series_uid) ==
             file.referenced_series_uids.end()) {
    std::string named;
    for (const auto& uid : file.referenced_series_uids) named += (named.empty() ? "" : ", ") + uid;
    fail(path, "it segments another series: its Referenced Series Sequence names " + named + ", the scan is series " +
                   scan.series_uid + "; open it on the scan it was made on");
  }
  if (!scan.frame_of_reference_uid.empty() && !file.frame_of_reference_uid.empty() &&
      scan.frame_of_reference_uid != file.frame_of_reference_uid) {
    fail(path, "another frame of reference: the SEG's Frame of Reference UID is " + file.frame_of_reference_uid +
                   ", the scan's " + scan.frame_of_reference_uid + " (their patient coordinates do not correspond)");
  }
}

/// The segments' names, IDs and colours (SegmentInfo), in the file's order.
std::vector<SegmentInfo> segmentInfos(const DicomSegFile& file) {
  std::vector<SegmentInfo> out;
  for (std::size_t s = 0; s < file.segments.size(); ++s) {
    const detail::DicomSegSegment& d = file.segments[s];
    SegmentInfo info;
    info.id = "Segment_" + std::to_string(d.number);
    info.name = !d.label.empty() ? d.label : !d.type.empty() ? d.type : "Segment " + std::to_string(d.number);
    info.category = d.category;
    info.type = d.type;
    info.color_rgb = d.has_lab ? d.rgb : detail::segmentPaletteColour(s);
    out.push_back(std::move(info));
  }
  return out;
}

/// The label layers being filled: voxels on the grid (0 = no segment), labels used per layer.
/// Voxel index on the grid of frame pixel n of a frame on slice k.
std::size_t voxelOf(const DicomSegFile& file, int k, std::size_t n) {
  return n + static_cast<std::size_t>(file.rows) * static_cast<std::size_t>(file.columns) * static_cast<std::size_t>(k);
}

/// Calls visit(n) for each inside pixel n of `frame` (whole empty bytes of the mask skipped);
/// stops and returns false as soon as visit() does.
template <typename Visit>
bool forEachInside(const DicomSegFile& file, const DicomSegFrame& frame, Visit&& visit) {
  const std::size_t pixels = static_cast<std::size_t>(file.rows) * static_cast<std::size_t>(file.columns);
  for (std::size_t b = 0; b < frame.mask.size(); ++b) {
    if (frame.mask[b] == 0) continue;
    for (std::size_t n = 8 * b; n < std::min(pixels, 8 * b + 8); ++n) {
      if (frame.inside(n) && !visit(n)) return false;
    }
  }
  return true;
}

/// True when none of the frames' inside pixels is taken in `layer` (by another segment).
bool fitsIn(const std::vector<std::uint8_t>& layer, const DicomSegFile& file, const std::vector<std::size_t>& frames,
            const std::vector<int>& k_of) {
  for (const std::size_t f : frames) {
    const bool free =
        forEachInside(file, file.frames[f], [&](std::size_t n) { return layer[voxelOf(file, k_of[f], n)] == 0; });
    if (!free) return false;
  }
  return true;
}

/// Puts the segment of `frames` into the first layer it fits in (a new one when none), as the
/// next label of that layer; sets info.layer, info.label_value and info.voxel_count.
void placeSegment(SegmentLayers& layers, const DicomSegFile& file, const std::vector<std::size_t>& frames,
                  const std::vector<int>& k_of, SegmentInfo& info) {
  const auto [l, label] = layers.take([&](const std::vector<std::uint8_t>& layer) { return fitsIn(layer, file, frames, k_of); });
  info.layer = static_cast<int>(l);
  info.label_value = label;
  std::vector<std::uint8_t>& layer = layers.voxels[l];
  for (const std::size_t f : frames) {
    forEachInside(file, file.frames[f], [&](std::size_t n) {
      std::uint8_t& v = layer[voxelOf(file, k_of[f], n)];
      if (v == 0) {  // a voxel two frames of the segment share counts once
        v = static_cast<std::uint8_t>(info.label_value);
        ++info.voxel_count;
      }
      return true;
    });
  }
}

/// The segmentation of `file` on `g`, frame f on slice k_of[f].
LoadedSegmentation assemble(const DicomSegFile& file, const haptics::VolumeGeometry& g, const std::vector<int>& k_of,
                            const fs::path& path, const VolumeLoadOptions& options) {
  LoadedSegmentation seg;
  seg.source = path;
  seg.from_dicom_seg = true;
  seg.frame_of_reference_uid = file.frame_of_reference_uid;
  seg.referenced_series_uids = file.referenced_series_uids;
  seg.segments = segmentInfos(file);
  std::map<int, std::size_t> index_of;  // Segment Number -> index
  for (std::size_t s = 0; s < file.segments.size(); ++s) index_of[file.segments[s].number] = s;
  std::vector<std::vector<std::size_t>> frames_of(file.segments.size());
  for (std::size_t f = 0; f < file.frames.size(); ++f) {
    const auto it = index_of.find(file.frames[f].segment);
    if (it == index_of.end()) {
      fail(path, "a damaged DICOM SEG: " + frameName(f, file.frames[f]) + " refers to segment " +
                     std::to_string(file.frames[f].segment) + ", which the Segment Sequence does not have");
    }
    frames_of[it->second].push_back(f);
  }
  SegmentLayers layers;
  layers.voxel_count = g.voxelCount();
  for (std::size_t s = 0; s < seg.segments.size(); ++s) {
    if (options.cancel != nullptr && options.cancel->load()) throw LoadCancelled(path.string() + ": loading cancelled");
    placeSegment(layers, file, frames_of[s], k_of, seg.segments[s]);
    if (seg.segments[s].voxel_count == 0) seg.notices.push_back("segment \"" + seg.segments[s].name + "\" is empty");
  }
  for (auto& voxels : layers.voxels) {
    seg.layers.push_back(
        std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(g, voxels, 1.0, 0.0)));
    voxels = {};  // the layer's copy is in the ScalarVolume
  }
  if (seg.layers.size() > 1) {
    seg.notices.push_back(std::to_string(seg.segments.size()) + " segments in " + std::to_string(seg.layers.size()) +
                          " layers (overlapping segments are in different layers)");
  }
  return seg;
}

}  // namespace

LoadedSegmentation loadDicomSegmentation(const fs::path& path, const LoadedVolume* scan,
                                         const VolumeLoadOptions& options) {
  const DicomSegFile file = detail::readDicomSeg(path, options);
  if (options.progress) options.progress(0.5);
  std::vector<std::string> notices = file.notices;
  haptics::VolumeGeometry g;
  const bool on_scan = scan != nullptr && scan->field != nullptr;
  if (on_scan) {
    checkReferences(file, scan->info, path, notices);
    g = scan->field->geometry();
  } else {
    g = ownGrid(file, path, notices);
  }
  const std::vector<int> k_of = sliceIndices(file, g, path, on_scan ? "the scan" : "the SEG's lowest frame");
  LoadedSegmentation seg = assemble(file, g, k_of, path, options);
  notices.insert(notices.end(), seg.notices.begin(), seg.notices.end());
  seg.notices = std::move(notices);
  if (options.progress) options.progress(1.0);
  return seg;
}

}  // namespace vh::io
