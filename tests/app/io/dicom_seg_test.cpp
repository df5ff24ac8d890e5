// DICOM SEG (DICOM PS3.3 A.51 Segmentation IOD, C.8.20): segmentations written by DCMTK's own
// writer from a known label map on a CT series (dicom_seg_fixtures.h), read back with the
// project's reader and compared voxel for voxel. The oracle is independent of the reader: the
// label map is on the CT files' own pixels, placed through their headers read with DCMTK.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "dicom_seg_fixtures.h"
#include "io_test_support.h"
#include "vh/io/dicom_seg.h"
#include "vh/io/segmentation.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using test::CtSeries;
using test::LabelMap;
using test::mismatches;
using test::readCtSeries;
using test::SegSpec;
using test::shapes;
using test::syntheticCt;
using test::TempDir;
using test::writeSeg;

// ---- the segments' description ---------------------------------------------------------------

/// Names, IDs, codes, colours (within 2/255 of the label map's) and the overlap in layers.
void expectSegments(const LoadedSegmentation& seg, const LabelMap& m) {
  ASSERT_EQ(seg.segments.size(), m.names.size());
  EXPECT_TRUE(seg.from_dicom_seg);
  for (std::size_t s = 0; s < m.names.size(); ++s) {
    const SegmentInfo& info = seg.segments[s];
    EXPECT_EQ(info.name, m.names[s]);
    EXPECT_EQ(info.id, "Segment_" + std::to_string(s + 1));
    EXPECT_EQ(info.category, "Tissue");
    EXPECT_EQ(info.type, m.types[s]);
    EXPECT_EQ(info.voxel_count, m.count(s)) << info.name;
    for (std::size_t c = 0; c < 3; ++c)
      EXPECT_NEAR(info.color_rgb[c], m.rgb[s][c], 2.0 / 255.0) << info.name << " channel " << c;
  }
  // The balls overlap, and the box overlaps ball B: they cannot share a layer.
  EXPECT_GE(seg.layers.size(), 2u);
  EXPECT_NE(seg.segments[0].layer, seg.segments[1].layer);
  EXPECT_NE(seg.segments[1].layer, seg.segments[2].layer);
  EXPECT_EQ(seg.find("sparse disc"), 3);
}

// ---- the tests -----------------------------------------------------------------------------

TEST(DicomSeg, ABinarySegOpensOnItsCtVoxelForVoxelWhateverTheFrameOrder) {
  TempDir dir("dicom-seg-binary");
  const CtSeries ct = syntheticCt(dir / "ct");
  ASSERT_EQ(ct.slices.size(), 12u);
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  int sparse_slices = 0;  // the sparse disc is on three slices only
  for (int k = 0; k < m.slices; ++k) {
    sparse_slices += std::any_of(m.inside[3].begin() + static_cast<std::ptrdiff_t>(m.at(0, 0, k)),
                                 m.inside[3].begin() + static_cast<std::ptrdiff_t>(m.at(0, 0, k + 1)),
                                 [](std::uint8_t v) { return v != 0; });
  }
  ASSERT_EQ(sparse_slices, 3);
  SegSpec in_order;
  in_order.shuffle_seed = 0;
  SegSpec shuffled;
  shuffled.shuffle_seed = 7;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "ordered.dcm", ct, m, in_order));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "shuffled-seg", ct, m, shuffled));  // no extension: found by content

  EXPECT_TRUE(isDicomSegmentationFile(dir / "shuffled-seg"));
  EXPECT_TRUE(isSegmentationFile(dir / "shuffled-seg"));
  EXPECT_FALSE(isDicomSegmentationFile(ct.slices.front().file));
  const LoadedSegmentation ordered = loadSegmentation(dir / "ordered.dcm", scan);
  const LoadedSegmentation seg = loadSegmentation(dir / "shuffled-seg", scan);
  EXPECT_EQ(mismatches(ordered, scan, ct, m), 0u);
  EXPECT_EQ(mismatches(seg, scan, ct, m), 0u);
  expectSegments(seg, m);
  for (const auto& n : seg.notices) EXPECT_EQ(n.find("read in this process"), std::string::npos) << n;
  EXPECT_EQ(seg.frame_of_reference_uid, ct.for_uid);
  EXPECT_EQ(seg.referenced_series_uids, std::vector<std::string>{ct.series_uid});
  // The layers are the scan's grid, and the frame order changes nothing.
  ASSERT_EQ(seg.layers.size(), ordered.layers.size());
  for (std::size_t l = 0; l < seg.layers.size(); ++l) {
    EXPECT_EQ(seg.layers[l]->geometry().dims, scan.field->geometry().dims);
    EXPECT_TRUE(seg.layers[l]->geometry().origin_W_m.isApprox(scan.field->geometry().origin_W_m, 1e-12));
    EXPECT_TRUE(seg.layers[l]->bytes() == ordered.layers[l]->bytes()) << "layer " << l;
  }
  // The comparison sees one voxel changed in the label map after the SEG was written.
  LabelMap changed = m;
  const std::size_t n = changed.at(ct.columns / 2, ct.rows / 2, static_cast<int>(ct.slices.size()) / 2);
  changed.inside[1][n] = changed.inside[1][n] != 0 ? 0 : 1;
  EXPECT_EQ(mismatches(seg, scan, ct, changed), 1u);
}

TEST(DicomSeg, AFractionalSegIsInsideAtHalfItsMaximum) {
  TempDir dir("dicom-seg-fractional");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  SegSpec spec;
  spec.fractional = true;
  spec.shuffle_seed = 3;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "fractional.dcm", ct, m, spec));
  const LoadedSegmentation seg = loadSegmentation(dir / "fractional.dcm", scan);
  EXPECT_EQ(mismatches(seg, scan, ct, m), 0u);
  expectSegments(seg, m);
  bool noticed = false;
  for (const auto& n : seg.notices)
    noticed = noticed || n.find("at least half the maximum (128 of 255)") != std::string::npos;
  EXPECT_TRUE(noticed) << "no notice of the threshold";
}

TEST(DicomSeg, WithoutAScanItOpensOnTheGridItsFramesSpan) {
  TempDir dir("dicom-seg-own-grid");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "seg.dcm", ct, m, SegSpec{}));
  const LoadedSegmentation seg = loadSegmentation(dir / "seg.dcm");
  expectSegments(seg, m);
  // Its grid is the scan's slices from the lowest frame to the highest: every one of its voxels
  // is the scan voxel at the same place, with the same segments.
  const LoadedSegmentation on_scan = loadSegmentation(dir / "seg.dcm", scan);
  const haptics::VolumeGeometry& g = seg.layers.front()->geometry();
  const haptics::VolumeGeometry& sg = scan.field->geometry();
  EXPECT_TRUE(g.direction_W.isApprox(sg.direction_W, 1e-6));
  EXPECT_TRUE(g.spacing_m.isApprox(sg.spacing_m, 1e-6));
  EXPECT_LT(g.dims[2], sg.dims[2]);  // the first and last CT slices hold no segment
  std::size_t wrong = 0;
  for (int k = 0; k < g.dims[2]; ++k) {
    for (int j = 0; j < g.dims[1]; ++j) {
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        const Eigen::Vector3d u = (sg.direction_W.transpose() * (p - sg.origin_W_m)).cwiseQuotient(sg.spacing_m);
        const Eigen::Vector3i v = u.array().round().cast<int>();
        EXPECT_LT((u - v.cast<double>()).norm(), 1e-3);
        for (std::size_t s = 0; s < seg.segments.size(); ++s) {
          const bool own = seg.label(seg.segments[s].layer, i, j, k) == seg.segments[s].label_value;
          const SegmentInfo& o = on_scan.segments[s];
          if (own != (on_scan.label(o.layer, v.x(), v.y(), v.z()) == o.label_value)) ++wrong;
        }
      }
    }
  }
  EXPECT_EQ(wrong, 0u);
}

TEST(DicomSeg, OnTheSharedCtHeadEveryVoxelMatches) {
  VH_REQUIRE_SHARED(folder, "ct/ct-head-small");
  TempDir dir("dicom-seg-ct-head");
  const CtSeries ct = readCtSeries(folder);
  ASSERT_GE(ct.slices.size(), 2u);
  const LoadedVolume scan = loadVolume(folder);
  ASSERT_EQ(scan.field->geometry().dims[2], static_cast<int>(ct.slices.size()));
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  SegSpec spec;
  spec.shuffle_seed = 11;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "head-seg.dcm", ct, m, spec));
  const LoadedSegmentation seg = loadSegmentation(dir / "head-seg.dcm", scan);
  EXPECT_EQ(mismatches(seg, scan, ct, m), 0u);
  expectSegments(seg, m);
}

TEST(DicomSeg, ASegThatDoesNotFitTheScanIsRefusedWithTheReason) {
  TempDir dir("dicom-seg-bad");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  SegSpec other_series;
  other_series.referenced_series = "1.2.826.0.1.3680043.8.498.1";
  SegSpec other_frame;
  other_frame.frame_of_reference = "1.2.826.0.1.3680043.8.498.2";
  SegSpec shifted;
  shifted.shift_first_frame_mm = 0.5 * ct.sliceSpacing();
  SegSpec spacing;
  spacing.pixel_spacing_scale = 1.25;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "other-series.dcm", ct, m, other_series));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "other-frame.dcm", ct, m, other_frame));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "shifted.dcm", ct, m, shifted));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "spacing.dcm", ct, m, spacing));
  for (const DicomIsolation isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    const auto error = [&](const char* name) {
      return test::loadErrorOf([&] { (void)loadSegmentation(dir / name, scan, options); });
    };
    std::string e = error("other-series.dcm");
    EXPECT_CONTAINS(e, "other-series.dcm");
    EXPECT_CONTAINS(e, "it segments another series: its Referenced Series Sequence names 1.2.826.0.1.3680043.8.498.1");
    EXPECT_CONTAINS(e, ct.series_uid);
    e = error("other-frame.dcm");
    EXPECT_CONTAINS(e, "another frame of reference: the SEG's Frame of Reference UID is 1.2.826.0.1.3680043.8.498.2");
    e = error("shifted.dcm");
    EXPECT_CONTAINS(e, "shifted.dcm");
    EXPECT_CONTAINS(e, "lies between slices of the scan (slice index");
    e = error("spacing.dcm");
    EXPECT_CONTAINS(e, "(Pixel Spacing, rows \\ columns) is not the scan's");
  }
}

TEST(DicomSeg, DamagedFilesAndOtherDicomAreRefusedWithoutACrash) {
  TempDir dir("dicom-seg-damaged");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "whole.dcm", ct, m, SegSpec{}));
  const std::string bytes = test::readFile(dir / "whole.dcm");
  test::writeFile(dir / "half.dcm", bytes.substr(0, bytes.size() / 2));
  test::writeFile(dir / "garbage.dcm", std::string(128, '\0') + "DICM" + std::string(300, '\x7f'));
  for (const DicomIsolation isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    std::string e = test::loadErrorOf([&] { (void)loadSegmentation(dir / "half.dcm", scan, options); });
    EXPECT_CONTAINS(e, "half.dcm");
    EXPECT_CONTAINS(e, "damaged");
    e = test::loadErrorOf([&] { (void)loadSegmentation(dir / "garbage.dcm", options); });
    EXPECT_CONTAINS(e, "garbage.dcm");
    EXPECT_CONTAINS(e, "damaged");
    e = test::loadErrorOf([&] { (void)loadSegmentation(ct.slices.front().file, scan, options); });
    EXPECT_CONTAINS(e, ct.slices.front().file.filename().string());
    EXPECT_CONTAINS(e, "not a DICOM SEG: its SOP Class is CTImageStorage (1.2.840.10008.5.1.4.1.1.2)");
    e = test::loadErrorOf([&] { (void)loadSegmentation(dir / "missing.dcm", options); });
    EXPECT_CONTAINS(e, "no such file");
  }
  EXPECT_FALSE(isSegmentationFile(dir / "garbage.dcm"));
}

// A SEG opened as a scan (the file, or a folder holding only it) names itself and says how to
// open it, instead of "two slices at the same position (X.dcm and X.dcm)": its frames are the
// segments, several at each slice position.
TEST(DicomSeg, ASegOpenedAsAScanNamesItselfAndPointsToOpenSegmentation) {
  TempDir dir("dicom-seg-as-scan");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  std::filesystem::create_directories(dir / "seg-only");
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "seg-only" / "seg.dcm", ct, m, SegSpec{}));
  for (const DicomIsolation isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    for (const std::filesystem::path& path : {dir / "seg-only" / "seg.dcm", dir / "seg-only"}) {
      const std::string e = test::loadErrorOf([&] { (void)loadVolume(path, options); });
      EXPECT_CONTAINS(e, "a DICOM Segmentation (SEG), not a scan");
      EXPECT_CONTAINS(e, "File > Open Segmentation");
      EXPECT_CONTAINS(e, "--segmentation");
      EXPECT_EQ(e.find("same position"), std::string::npos) << e;
    }
  }
}

// ---- sequences nested too deep ---------------------------------------------------------------

/// A little-endian value of `bytes` bytes.
std::string le(std::uint32_t v, int bytes) {
  std::string s;
  for (int i = 0; i < bytes; ++i) s += static_cast<char>((v >> (8 * i)) & 0xff);
  return s;
}

/// Explicit VR little endian element with a 2-byte length (PS3.5 7.1.2).
std::string shortElement(std::uint16_t group, std::uint16_t element, const char* vr, std::string value) {
  if (value.size() % 2 != 0) value += '\0';
  return le(group, 2) + le(element, 2) + vr + le(static_cast<std::uint32_t>(value.size()), 2) + value;
}

/// A SEG-class DICOM file (preamble, meta information, SOP Class UID) holding `levels` nested
/// sequences of undefined length: Content Sequence (0040,A730) > item > Content Sequence ...,
/// explicit or implicit VR, each closed by its delimiters or (cut_short) left open at the end
/// of the file; or, with in_meta, nested in a group-0002 element of the meta information.
std::string nestedSeg(std::size_t levels, bool explicit_vr, bool cut_short, bool in_meta) {
  const std::string sop = kSegmentationStorageUid;
  const char* syntax = explicit_vr ? "1.2.840.10008.1.2.1" : "1.2.840.10008.1.2";
  const std::string undefined = le(0xFFFFFFFFu, 4);
  const std::string open_item = le(0xFFFE, 2) + le(0xE000, 2) + undefined;
  const std::string close = le(0xFFFE, 2) + le(0xE00D, 2) + le(0, 4) + le(0xFFFE, 2) + le(0xE0DD, 2) + le(0, 4);
  const auto nest = [&](std::uint16_t group, std::uint16_t element, bool explicit_here) {
    const std::string sq = le(group, 2) + le(element, 2) + (explicit_here ? std::string("SQ") + le(0, 2) : "") + undefined;
    std::string s;
    for (std::size_t n = 0; n < levels; ++n) s += sq + open_item;
    if (!cut_short) {
      for (std::size_t n = 0; n < levels; ++n) s += close;
    }
    return s;
  };
  std::string meta = shortElement(0x0002, 0x0002, "UI", sop) + shortElement(0x0002, 0x0003, "UI", "1.2.3.4") +
                     shortElement(0x0002, 0x0010, "UI", syntax);
  if (in_meta) meta += nest(0x0002, 0x0100, true);
  meta = shortElement(0x0002, 0x0000, "UL", le(static_cast<std::uint32_t>(meta.size()), 4)) + meta;
  std::string data;
  std::string uid = sop;
  if (uid.size() % 2 != 0) uid += '\0';
  data = explicit_vr ? shortElement(0x0008, 0x0016, "UI", sop)
                     : le(0x0008, 2) + le(0x0016, 2) + le(static_cast<std::uint32_t>(uid.size()), 4) + uid;
  if (!in_meta) data += nest(0x0040, 0xA730, explicit_vr);
  return std::string(128, '\0') + "DICM" + meta + data;
}

// Sequences nested 100,000 deep (1.6 to 3.2 MB): DCMTK 3.6.7 parses nested sequences by
// recursion without a limit, and such a file overflows its stack (dcmdump dies of SIGSEGV on
// these files from about 6,000 levels). The SEG reader refuses them before DCMTK parses, in the
// reader process and in this one, and the check of a file's SOP Class, which runs in the
// application's own process, does not parse them. A file nested 100 deep is parsed (its error is
// the next check's: no Segmentation Type).
TEST(DicomSeg, SequencesNestedTooDeepAreRefusedBeforeDcmtkParsesThem) {
  TempDir dir("dicom-seg-nested");
  const std::vector<std::pair<std::string, std::string>> deep = {
      {"explicit-cut-short.dcm", nestedSeg(100000, true, true, false)},
      {"implicit-delimited.dcm", nestedSeg(100000, false, false, false)},
      {"in-meta-information.dcm", nestedSeg(100000, true, true, true)},
  };
  for (const auto& [name, bytes] : deep) test::writeFile(dir / name, bytes);
  test::writeFile(dir / "nested-100.dcm", nestedSeg(100, true, false, false));
  for (const DicomIsolation isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    for (const auto& [name, bytes] : deep) {
      const std::string e = test::loadErrorOf([&] { (void)loadDicomSegmentation(dir / name, nullptr, options); });
      EXPECT_CONTAINS(e, name);
      EXPECT_CONTAINS(e, "its sequences nest more than 128 levels deep");
      EXPECT_FALSE(isDicomSegmentationFile(dir / name)) << name;
    }
    const std::string e = test::loadErrorOf([&] { (void)loadDicomSegmentation(dir / "nested-100.dcm", nullptr, options); });
    EXPECT_CONTAINS(e, "Segmentation Type \"\" is neither BINARY nor FRACTIONAL");
  }
  EXPECT_TRUE(isDicomSegmentationFile(dir / "nested-100.dcm"));
}

}  // namespace
}  // namespace vh::io
