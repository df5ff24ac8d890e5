// RT Structure Set contours rasterised on the scan's grid (dicom_rtstruct.h): each contour's
// slice, the even-odd scanline fill of each ROI's contours slice by slice, the references
// checked against the scan, and the label layers of the overlapping ROIs.
//
// A grid voxel (i, j, k) lies at origin + D diag(spacing) (i, j, k) in W = LPS in m, D's columns
// the i, j, k axes (haptics::VolumeGeometry), as for a DICOM SEG (dicom_seg_grid.cpp). A contour
// point p (LPS mm) has voxel coordinates u = D^T (p 1e-3 - origin) / spacing: u.x, u.y in the
// slice plane (voxel centres at whole numbers), u.z along the slice normal.
//
// Scan conversion: Foley, van Dam, Feiner, Hughes, "Computer Graphics: Principles and
// Practice" (2nd ed., 3.6 "Filling Polygons"): per row of voxel centres, the crossings of all
// edges with the row, sorted; the spans between crossings 1-2, 3-4, ... are inside (the
// even-odd rule). An edge counts for row v when its ends are on different sides of v, taken
// half-open (y0 <= v < y1 or y1 <= v < y0), so that a vertex on the row is counted once.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "dicom_rtstruct_internal.h"
#include "dicom_seg_internal.h"
#include "loader_internal.h"
#include "vh/io/dicom_rtstruct.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using detail::fail;
using detail::RtStructContour;
using detail::RtStructFile;
using detail::SegmentLayers;
using detail::RtStructRoi;

/// Labels per layer (the layers are uint8).
/// Self-intersection is looked for in contours of at most this many points (the test is
/// quadratic in the points; it only decides a notice).
constexpr std::size_t kMaxPointsCheckedForCrossing = 2000;

std::string num(double v, int decimals = 2) {
  char s[64];
  std::snprintf(s, sizeof(s), "%.*f", decimals, v);
  return s;
}

std::string roiName(const RtStructRoi& roi) {
  return "ROI " + std::to_string(roi.number) + " (\"" + roi.name + "\")";
}

/// True when `list` names `uid`.
bool names(const std::vector<std::string>& list, const std::string& uid) {
  return std::find(list.begin(), list.end(), uid) != list.end();
}

std::string joined(const std::vector<std::string>& list) {
  std::string s;
  for (const auto& uid : list) s += (s.empty() ? "" : ", ") + uid;
  return s;
}

/// The scan's DICOM UIDs against the structure set's references (see loadDicomRtStruct()).
void checkReferences(const RtStructFile& file, const VolumeInfo& scan, const fs::path& path,
                     std::vector<std::string>& notices) {
  if (scan.frame_of_reference_uid.empty() && scan.series_uid.empty()) {
    notices.push_back("the scan has no DICOM UIDs (" + (scan.format.empty() ? "not DICOM" : scan.format) +
                      "), so the structure set's references were not checked: placed by its patient coordinates only");
    return;
  }
  const std::string& for_uid = scan.frame_of_reference_uid;
  if (!for_uid.empty() && !file.frame_of_reference_uids.empty() && !names(file.frame_of_reference_uids, for_uid)) {
    fail(path, "another frame of reference: the RT Structure Set's Referenced Frame of Reference Sequence names " +
                   joined(file.frame_of_reference_uids) + ", the scan's Frame of Reference UID is " + for_uid +
                   " (their patient coordinates do not correspond); open it on the scan it was drawn on");
  }
  for (const RtStructRoi& roi : file.rois) {
    if (!for_uid.empty() && !roi.frame_of_reference_uid.empty() && roi.frame_of_reference_uid != for_uid) {
      fail(path, "another frame of reference: " + roiName(roi) + " is in frame of reference " +
                     roi.frame_of_reference_uid + ", the scan's is " + for_uid +
                     " (their patient coordinates do not correspond)");
    }
  }
  if (!scan.series_uid.empty() && !file.referenced_series_uids.empty() &&
      !names(file.referenced_series_uids, scan.series_uid)) {
    fail(path, "it outlines another series: its RT Referenced Series Sequence names " +
                   joined(file.referenced_series_uids) + ", the scan is series " + scan.series_uid +
                   "; open it on the scan it was drawn on");
  }
  if (file.referenced_series_uids.empty()) {
    notices.push_back("the structure set names no referenced series (RT Referenced Series Sequence): placed by its "
                      "patient coordinates only");
  }
}

/// A closed contour in one slice: its slice index and its points in voxel coordinates (u.x, u.y).
struct SliceContour {
  int k = 0;
  std::vector<Eigen::Vector2d> points;
};

/// The contour's slice on `g` and its points in the slice's voxel coordinates.
/// @throws LoadError when a point lies more than kRtStructOnSliceFraction of the slice spacing
///         off the slice nearest the points' mean, or that slice is outside the scan.
SliceContour onSlice(const RtStructContour& c, const haptics::VolumeGeometry& g, const std::string& name,
                     const fs::path& path) {
  SliceContour out;
  double mean_z = 0.0;
  std::vector<double> z;
  for (const Eigen::Vector3d& p : c.points_mm) {
    const Eigen::Vector3d u = (g.direction_W.transpose() * (p * 1e-3 - g.origin_W_m)).cwiseQuotient(g.spacing_m);
    out.points.emplace_back(u.x(), u.y());
    z.push_back(u.z());
    mean_z += u.z() / static_cast<double>(c.points_mm.size());
  }
  const double k = std::round(mean_z);
  const double off = std::abs(mean_z - k);
  if (off > kRtStructOnSliceFraction) {
    fail(path, name + " lies between slices of the scan (at slice index " + num(mean_z) + ", " + num(off * 100.0, 0) +
                   " % of a slice off slice " + num(k, 0) + "): not drawn on the scan's slices");
  }
  for (const double zp : z) {
    if (std::abs(zp - k) > kRtStructOnSliceFraction) {
      fail(path, name + " is not in the plane of a scan slice: its points lie at slice indices " + num(zp) + " and " +
                     num(mean_z) + " (mean)");
    }
  }
  if (k < 0.0 || k >= g.dims[2]) {
    fail(path, name + " lies outside the scan (slice index " + num(k, 0) + " of 0.." + std::to_string(g.dims[2] - 1) +
                   ")");
  }
  out.k = static_cast<int>(k);
  return out;
}

/// True when two edges of `p` that share no vertex cross (a self-intersecting polygon).
bool crossesItself(const std::vector<Eigen::Vector2d>& p) {
  const std::size_t n = p.size();
  if (n < 4 || n > kMaxPointsCheckedForCrossing) return false;
  const auto side = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    const double d = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    return (d > 0.0) - (d < 0.0);
  };
  for (std::size_t e = 0; e < n; ++e) {
    const Eigen::Vector2d &a = p[e], &b = p[(e + 1) % n];
    for (std::size_t f = e + 2; f < n; ++f) {
      if ((f + 1) % n == e) continue;  // adjacent through the closing edge
      const Eigen::Vector2d &c = p[f], &d = p[(f + 1) % n];
      if (std::max(a.x(), b.x()) < std::min(c.x(), d.x()) || std::max(c.x(), d.x()) < std::min(a.x(), b.x()) ||
          std::max(a.y(), b.y()) < std::min(c.y(), d.y()) || std::max(c.y(), d.y()) < std::min(a.y(), b.y())) {
        continue;
      }
      if (side(a, b, c) * side(a, b, d) < 0 && side(c, d, a) * side(c, d, b) < 0) return true;
    }
  }
  return false;
}

/// Fills the closed contours `polys` of one slice k by the even-odd rule at voxel centres
/// (scanline fill, see the file comment), toggling each voxel of `inside` (one slice, i + dims0 j).
void fillSlice(const std::vector<const SliceContour*>& polys, const haptics::VolumeGeometry& g,
               std::vector<std::uint8_t>& inside) {
  double y_min = INFINITY, y_max = -INFINITY;
  for (const SliceContour* c : polys) {
    for (const auto& p : c->points) {
      y_min = std::min(y_min, p.y());
      y_max = std::max(y_max, p.y());
    }
  }
  const int j0 = std::max(0, static_cast<int>(std::ceil(y_min)));
  const int j1 = std::min(g.dims[1] - 1, static_cast<int>(std::floor(y_max)));
  std::vector<double> xs;
  for (int j = j0; j <= j1; ++j) {
    xs.clear();
    const double v = j;
    for (const SliceContour* c : polys) {
      const std::size_t n = c->points.size();
      for (std::size_t e = 0; e < n; ++e) {
        const Eigen::Vector2d& a = c->points[e];
        const Eigen::Vector2d& b = c->points[(e + 1) % n];
        if ((a.y() <= v) == (b.y() <= v)) continue;  // half-open: the edge does not cross row v
        xs.push_back(a.x() + (v - a.y()) * (b.x() - a.x()) / (b.y() - a.y()));
      }
    }
    std::sort(xs.begin(), xs.end());
    for (std::size_t m = 0; m + 1 < xs.size(); m += 2) {
      const int i0 = std::max(0, static_cast<int>(std::ceil(xs[m])));
      const int i1 = std::min(g.dims[0] - 1, static_cast<int>(std::ceil(xs[m + 1])) - 1);  // centres i < x1
      for (int i = i0; i <= i1; ++i) inside[static_cast<std::size_t>(i) + static_cast<std::size_t>(g.dims[0]) * j] = 1;
    }
  }
}

/// The voxels (indices i + dims0 (j + dims1 k), ascending) of `roi` on `g`.
std::vector<std::size_t> rasterise(const RtStructRoi& roi, const haptics::VolumeGeometry& g, const fs::path& path,
                                   std::vector<std::string>& notices) {
  std::vector<SliceContour> contours;
  std::size_t skipped = 0, degenerate = 0, crossing = 0;
  for (std::size_t c = 0; c < roi.contours.size(); ++c) {
    const RtStructContour& contour = roi.contours[c];
    if ((contour.type != "CLOSED_PLANAR" && contour.type != "CLOSEDPLANAR_XOR") || contour.points_mm.empty()) {
      ++skipped;
      continue;
    }
    contours.push_back(onSlice(contour, g, roiName(roi) + " contour " + std::to_string(c + 1), path));
    if (contours.back().points.size() < 3) ++degenerate;
    else if (crossesItself(contours.back().points)) ++crossing;
  }
  const std::string name = roiName(roi);
  if (skipped > 0) {
    notices.push_back(name + ": " + std::to_string(skipped) +
                      " contour(s) that are not CLOSED_PLANAR (POINT, OPEN_PLANAR, OPEN_NONPLANAR) or have no "
                      "points were skipped");
  }
  if (degenerate > 0) {
    notices.push_back(name + ": " + std::to_string(degenerate) +
                      " closed contour(s) of fewer than 3 points enclose nothing (filled by the even-odd rule)");
  }
  if (crossing > 0) {
    notices.push_back(name + ": " + std::to_string(crossing) +
                      " contour(s) cross themselves; filled by the even-odd rule (doubly enclosed parts are holes)");
  }
  std::stable_sort(contours.begin(), contours.end(), [](const auto& a, const auto& b) { return a.k < b.k; });
  const std::size_t slice = static_cast<std::size_t>(g.dims[0]) * static_cast<std::size_t>(g.dims[1]);
  std::vector<std::size_t> voxels;
  std::vector<std::uint8_t> inside(slice, 0);
  for (std::size_t a = 0; a < contours.size();) {
    std::size_t b = a;
    std::vector<const SliceContour*> polys;
    while (b < contours.size() && contours[b].k == contours[a].k) polys.push_back(&contours[b++]);
    std::fill(inside.begin(), inside.end(), 0);
    fillSlice(polys, g, inside);
    for (std::size_t n = 0; n < slice; ++n) {
      if (inside[n] != 0) voxels.push_back(n + slice * static_cast<std::size_t>(contours[a].k));
    }
    a = b;
  }
  return voxels;
}

/// The label layers being filled: voxels on the grid (0 = no ROI), labels used per layer.
/// Puts `voxels` into the first layer where none is taken (a new one when none) as the next
/// label of that layer; sets info.layer, info.label_value and info.voxel_count.
/// Layers of overlapping ROIs opened at most: each is a label map of the scan's size (1,000
/// overlapping one-circle ROIs took 6.0 GB and over a minute); real structure sets overlap a few
/// deep (a target inside its organ inside the body).
constexpr std::size_t kMaxRoiLayers = 32;

void place(SegmentLayers& layers, const std::vector<std::size_t>& voxels, SegmentInfo& info, const fs::path& path) {
  const auto [l, label] = layers.take([&](const std::vector<std::uint8_t>& layer) {
    return std::none_of(voxels.begin(), voxels.end(), [&](std::size_t n) { return layer[n] != 0; });
  });
  if (layers.voxels.size() > kMaxRoiLayers) {
    char mb[32];
    std::snprintf(mb, sizeof mb, "%.1f", static_cast<double>(layers.voxel_count) / 1e6);
    fail(path, "ROI \"" + info.name + "\" overlaps ROIs in " + std::to_string(kMaxRoiLayers) +
                   " layers already: at most " + std::to_string(kMaxRoiLayers) +
                   " layers of overlapping ROIs are opened (each a label map of the scan's size, " + mb + " MB)");
  }
  info.layer = static_cast<int>(l);
  info.label_value = label;
  for (const std::size_t n : voxels) layers.voxels[l][n] = static_cast<std::uint8_t>(info.label_value);
  info.voxel_count = voxels.size();
}

}  // namespace

LoadedSegmentation loadDicomRtStruct(const fs::path& path, const LoadedVolume* scan, const VolumeLoadOptions& options) {
  if (scan == nullptr || scan->field == nullptr) {
    fail(path, "an RT Structure Set holds contours drawn on a CT, not voxels: open that scan first, then the "
               "structure set on it");
  }
  const RtStructFile file = detail::readDicomRtStruct(path, options);
  if (options.progress) options.progress(0.5);
  LoadedSegmentation seg;
  seg.source = path;
  seg.notices = file.notices;
  seg.frame_of_reference_uid = file.frame_of_reference_uids.empty() ? "" : file.frame_of_reference_uids.front();
  seg.referenced_series_uids = file.referenced_series_uids;
  checkReferences(file, scan->info, path, seg.notices);
  const haptics::VolumeGeometry& g = scan->field->geometry();
  SegmentLayers layers;
  layers.voxel_count = g.voxelCount();
  for (const RtStructRoi& roi : file.rois) {
    if (options.cancel != nullptr && options.cancel->load()) throw LoadCancelled(path.string() + ": loading cancelled");
    const bool closed = std::any_of(roi.contours.begin(), roi.contours.end(), [](const RtStructContour& c) {
      return c.type == "CLOSED_PLANAR" || c.type == "CLOSEDPLANAR_XOR";
    });
    if (!closed) {
      const char* why =
          roi.contours.empty() ? " has no contours" : " has no closed contours (POINT or OPEN_PLANAR only)";
      seg.notices.push_back(roiName(roi) + why + ": skipped");
      continue;
    }
    const std::vector<std::size_t> voxels = rasterise(roi, g, path, seg.notices);
    SegmentInfo info;
    info.id = "ROI_" + std::to_string(roi.number);
    info.name = roi.name.empty() ? "ROI " + std::to_string(roi.number) : roi.name;
    info.color_rgb = detail::segmentPaletteColour(seg.segments.size());
    if (roi.has_color) {
      for (std::size_t c = 0; c < 3; ++c) info.color_rgb[c] = roi.color[c] / 255.0;
    }
    place(layers, voxels, info, path);
    if (info.voxel_count == 0) seg.notices.push_back("segment \"" + info.name + "\" is empty (no voxel centre inside)");
    seg.segments.push_back(std::move(info));
  }
  if (seg.segments.empty()) fail(path, "no ROI with closed contours (CLOSED_PLANAR): nothing to show");
  for (auto& voxels : layers.voxels) {
    seg.layers.push_back(
        std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(g, voxels, 1.0, 0.0)));
    voxels = {};
  }
  if (seg.layers.size() > 1) {
    seg.notices.push_back(std::to_string(seg.segments.size()) + " ROIs in " + std::to_string(seg.layers.size()) +
                          " layers (overlapping ROIs are in different layers)");
  }
  if (options.progress) options.progress(1.0);
  return seg;
}

}  // namespace vh::io
