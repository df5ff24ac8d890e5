// Segmentations: 3D Slicer's .seg.nrrd and label-map NRRDs (see segmentation.h); DICOM SEGs are
// recognised here and read by dicom_seg.cpp / dicom_seg_grid.cpp, RT Structure Sets by
// dicom_rtstruct.cpp / dicom_rtstruct_grid.cpp.
#include "vh/io/segmentation.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>

#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkImageGaussianSmooth.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>

#include "dicom_seg_internal.h"
#include "loader_internal.h"
#include "nifti_internal.h"
#include "reader_checks.h"
#include "vh/io/dicom_rtstruct.h"
#include "vh/io/dicom_seg.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using detail::fail;

constexpr int kMaxLabelMapSegments = 4096;

/// A qualitative palette for label maps without colours (Slicer's first generic colours' hues).
constexpr std::array<std::array<double, 3>, 10> kPalette = {{{0.50, 0.68, 0.50},
                                                            {0.95, 0.84, 0.57},
                                                            {0.69, 0.48, 0.40},
                                                            {0.44, 0.72, 0.82},
                                                            {0.87, 0.51, 0.36},
                                                            {0.56, 0.45, 0.77},
                                                            {0.85, 0.40, 0.55},
                                                            {0.35, 0.60, 0.35},
                                                            {0.90, 0.78, 0.20},
                                                            {0.40, 0.55, 0.90}}};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

/// Rounds a label voxel; false when it is not an integer (a label map holds integers).
bool integerLabel(double v, int& label) {
  if (!std::isfinite(v) || std::abs(v - std::round(v)) > 1e-6 || std::abs(v) > 1e9) return false;
  label = static_cast<int>(std::lround(v));
  return true;
}

/// Counts the voxels of each label of `layer` (labels must be integers).
std::map<int, std::size_t> labelCounts(const haptics::ScalarVolume& layer, const fs::path& path) {
  std::map<int, std::size_t> counts;
  const auto& d = layer.geometry().dims;
  for (int k = 0; k < d[2]; ++k) {
    for (int j = 0; j < d[1]; ++j) {
      for (int i = 0; i < d[0]; ++i) {
        int label = 0;
        if (!integerLabel(layer.voxel(i, j, k), label)) {
          fail(path, "voxel (" + std::to_string(i) + ", " + std::to_string(j) + ", " + std::to_string(k) +
                         ") is not an integer label: not a segmentation");
        }
        ++counts[label];
        if (counts.size() > kMaxLabelMapSegments + 1) {
          fail(path, "more than " + std::to_string(kMaxLabelMapSegments) + " distinct labels: not a label map");
        }
      }
    }
  }
  return counts;
}

/// "SegmentN_Key" -> value of segment N, or "" when absent.
std::string segmentKey(const std::map<std::string, std::string>& kv, int n, const char* key) {
  const auto it = kv.find("Segment" + std::to_string(n) + "_" + key);
  return it == kv.end() ? std::string() : detail::trim(it->second);
}

/// Loads a NRRD segmentation (.seg.nrrd or label map) or a NIfTI label map on its own grid.
LoadedSegmentation loadNrrdSegmentation(const fs::path& path, const VolumeLoadOptions& options);

/// The reader for `path`: a NRRD segmentation by its extension, a DICOM SEG by ".dcm" or the
/// DICOM preamble (an RT Structure Set, by the SOP Class of its meta header, is rasterised on the
/// scan; a DICOM file of another kind gets the DICOM SEG reader's error naming its SOP Class),
/// else "not a segmentation".
LoadedSegmentation loadAnySegmentation(const fs::path& path, const LoadedVolume* scan,
                                       const VolumeLoadOptions& options) {
  // Before anything opens it: a FIFO would block the open (and the window), a device never end.
  detail::requireRegularFile(path, path);
  const auto ext = lower(path.extension().string());
  if (ext == ".nrrd" || ext == ".nhdr" || detail::isNiftiFileName(path)) return loadNrrdSegmentation(path, options);
  if (isDicomRtStructFile(path)) return loadDicomRtStruct(path, scan, options);
  if (ext == ".dcm" || detail::hasDicomPreamble(path)) return loadDicomSegmentation(path, scan, options);
  fail(path,
       "not a segmentation: expected a 3D Slicer .seg.nrrd, a label-map .nrrd / .nhdr / .nii / .nii.gz, a DICOM "
       "SEG or an RT Structure Set");
}

}  // namespace

namespace detail {

std::array<double, 3> segmentPaletteColour(std::size_t n) { return kPalette[n % kPalette.size()]; }

}  // namespace detail

int LoadedSegmentation::find(const std::string& name_or_id) const {
  const std::string wanted = lower(detail::trim(name_or_id));
  for (std::size_t s = 0; s < segments.size(); ++s) {
    if (lower(segments[s].name) == wanted) return static_cast<int>(s);
  }
  for (std::size_t s = 0; s < segments.size(); ++s) {
    if (lower(segments[s].id) == wanted) return static_cast<int>(s);
  }
  return -1;
}

int LoadedSegmentation::label(int layer, int i, int j, int k) const noexcept {
  if (layer < 0 || static_cast<std::size_t>(layer) >= layers.size() || !layers[static_cast<std::size_t>(layer)]) {
    return 0;
  }
  return static_cast<int>(std::lround(layers[static_cast<std::size_t>(layer)]->voxel(i, j, k)));
}

bool LoadedSegmentation::nearestVoxel(const Eigen::Vector3d& p_W_m, std::array<int, 3>& ijk) const noexcept {
  if (layers.empty() || !layers.front()) return false;
  const haptics::ScalarVolume& grid = *layers.front();
  const Eigen::Vector3d q = grid.gridCoordinates(p_W_m);
  std::array<int, 3> v{};
  for (int a = 0; a < 3; ++a) {
    if (!(q[a] > -0.5 && q[a] < grid.geometry().dims[a] - 0.5)) return false;  // NaN too
    v[a] = static_cast<int>(std::lround(q[a]));
    if (v[a] < 0 || v[a] >= grid.geometry().dims[a]) return false;
  }
  ijk = v;
  return true;
}

LoadedSegmentation loadSegmentation(const fs::path& path, const VolumeLoadOptions& options) {
  return loadAnySegmentation(path, nullptr, options);
}

LoadedSegmentation loadSegmentation(const fs::path& path, const LoadedVolume& scan, const VolumeLoadOptions& options) {
  return loadAnySegmentation(path, &scan, options);
}

namespace {

/// Slicer's segment `n` (the Segment<n>_ keys of `kv`): its ID and name (defaults
/// "Segment_<n+1>"), label value (default 1), layer (default 0) and colour (else the palette's).
/// @throws LoadError naming `path` for a label outside 0..65535 or a layer outside 0..255.
SegmentInfo slicerSegment(const std::map<std::string, std::string>& kv, int n, const fs::path& path) {
  SegmentInfo s;
  s.id = segmentKey(kv, n, "ID");
  s.name = segmentKey(kv, n, "Name");
  if (s.id.empty()) s.id = "Segment_" + std::to_string(n + 1);
  if (s.name.empty()) s.name = s.id;
  const std::string label = segmentKey(kv, n, "LabelValue");
  const auto label_value = label.empty() ? std::optional<long long>(1) : detail::parseInt(label);
  if (!label_value || *label_value < 0 || *label_value > 65535) {
    fail(path, "Segment" + std::to_string(n) + "_LabelValue \"" + label + "\" is not a label (0..65535)");
  }
  s.label_value = static_cast<int>(*label_value);
  const std::string layer = segmentKey(kv, n, "Layer");
  const auto layer_value = layer.empty() ? std::optional<long long>(0) : detail::parseInt(layer);
  if (!layer_value || *layer_value < 0 || *layer_value > 255) {
    fail(path, "Segment" + std::to_string(n) + "_Layer \"" + layer + "\" is not a layer index");
  }
  s.layer = static_cast<int>(*layer_value);
  const auto rgb = detail::splitWords(segmentKey(kv, n, "Color"));
  s.color_rgb = detail::segmentPaletteColour(static_cast<std::size_t>(n));
  if (rgb.size() == 3) {
    for (std::size_t c = 0; c < 3; ++c) {
      if (const auto v = detail::parseDouble(rgb[c])) s.color_rgb[c] = std::clamp(*v, 0.0, 1.0);
    }
  }
  return s;
}

/// A label map without segment names: one segment per nonzero label of the first layer, named by
/// value, with a notice saying so.
/// @throws LoadError naming `path` for a label outside 0..65535.
void addLabelMapSegments(LoadedSegmentation& seg, const fs::path& path) {
  const auto counts = labelCounts(*seg.layers.front(), path);
  std::size_t n = 0;
  for (const auto& [label, count] : counts) {
    if (label == 0) continue;
    if (label < 0 || label > 65535) fail(path, "label " + std::to_string(label) + " is outside 0..65535");
    SegmentInfo s;
    s.id = "Label_" + std::to_string(label);
    s.name = "Label " + std::to_string(label);
    s.label_value = label;
    s.voxel_count = count;
    s.color_rgb = detail::segmentPaletteColour(n++);
    seg.segments.push_back(std::move(s));
  }
  seg.notices.push_back("a label map without segment names: " + std::to_string(seg.segments.size()) +
                        " label(s), named by value");
}

LoadedSegmentation loadNrrdSegmentation(const fs::path& path, const VolumeLoadOptions& options) {
  if (!fs::exists(path)) fail(path, "no such file");
  // A NIfTI label map names no segments: each label is one.
  const std::map<std::string, std::string> kv =
      detail::isNiftiFileName(path) ? std::map<std::string, std::string>{} : detail::readNrrdKeyValues(path);

  LoadedSegmentation seg;
  seg.source = path;
  // Slicer's segments: Segment0_..., Segment1_..., contiguous from 0.
  int max_layer = 0;
  for (int n = 0; kv.count("Segment" + std::to_string(n) + "_LabelValue") != 0 ||
                  kv.count("Segment" + std::to_string(n) + "_Name") != 0;
       ++n) {
    SegmentInfo s = slicerSegment(kv, n, path);
    max_layer = std::max(max_layer, s.layer);
    seg.segments.push_back(std::move(s));
  }
  seg.from_slicer = !seg.segments.empty();

  // The label layers, read like any NRRD (in the reader process when it is found).
  for (int layer = 0; layer <= max_layer; ++layer) {
    VolumeLoadOptions layer_options = options;
    layer_options.nrrd_layer = layer;
    LoadedVolume v = loadVolume(path, layer_options);
    for (const auto& n : v.info.notices) {
      if (n.rfind("layer ", 0) != 0) seg.notices.push_back(n);
    }
    seg.layers.push_back(std::move(v.field));
  }

  if (seg.from_slicer) {
    std::vector<std::map<int, std::size_t>> counts(seg.layers.size());
    for (std::size_t l = 0; l < seg.layers.size(); ++l) counts[l] = labelCounts(*seg.layers[l], path);
    for (auto& s : seg.segments) {
      const auto& c = counts[static_cast<std::size_t>(s.layer)];
      const auto it = c.find(s.label_value);
      s.voxel_count = it == c.end() ? 0 : it->second;
      if (s.voxel_count == 0) seg.notices.push_back("segment \"" + s.name + "\" is empty");
    }
  } else {
    addLabelMapSegments(seg, path);
  }
  if (seg.segments.empty()) fail(path, "no segments: every voxel is 0");
  return seg;
}

}  // namespace

LoadedSegmentation segmentationFromLabels(std::shared_ptr<const haptics::ScalarVolume> labels, const fs::path& source,
                                          const std::map<int, std::string>& names) {
  if (labels == nullptr) fail(source, "no label volume");
  LoadedSegmentation seg;
  seg.source = source;
  seg.layers.push_back(std::move(labels));
  addLabelMapSegments(seg, source);
  if (seg.segments.empty()) fail(source, "no segments: every voxel is 0");
  for (const auto& entry : names) {
    const int label = entry.first;  // not a structured binding: clang 14 cannot capture one in a lambda
    const std::string& name = entry.second;
    const auto it = std::find_if(seg.segments.begin(), seg.segments.end(),
                                 [label](const SegmentInfo& s) { return s.label_value == label; });
    if (it == seg.segments.end()) fail(source, "a name for label " + std::to_string(label) + ", which no voxel has");
    it->name = name;
  }
  if (!names.empty()) seg.notices.clear();  // named: not "a label map without segment names"
  return seg;
}

bool isSegmentationFile(const fs::path& path) noexcept {
  try {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) return false;  // never open a FIFO or device to sniff it
    const std::string name = lower(path.filename().string());
    if (name.size() > 9 && name.compare(name.size() - 9, 9, ".seg.nrrd") == 0) return true;
    if (detail::isNiftiFileName(path)) return detail::isNiftiLabelMap(path);
    const auto ext = lower(path.extension().string());
    if (ext != ".nrrd" && ext != ".nhdr") return isDicomSegmentationFile(path) || isDicomRtStructFile(path);
    const auto kv = detail::readNrrdKeyValues(path);
    return kv.count("Segment0_LabelValue") != 0 || kv.count("Segment0_Name") != 0;
  } catch (...) {
    return false;
  }
}

std::string segmentationFileDialogFilter() {
  return "Segmentations (*.seg.nrrd *.nrrd *.nhdr *.nii *.nii.gz *.hdr *.dcm);;All files (*)";
}

std::shared_ptr<const haptics::ScalarVolume> segmentIndicatorField(const LoadedSegmentation& seg,
                                                                  const std::vector<int>& segments,
                                                                  double sigma_voxels) {
  if (segments.empty()) throw std::invalid_argument("segmentIndicatorField: no segments chosen");
  if (!std::isfinite(sigma_voxels) || sigma_voxels < 0.0) {
    throw std::invalid_argument("segmentIndicatorField: the smoothing must be a finite sigma >= 0 voxels");
  }
  // Which labels of which layer are inside.
  std::vector<std::set<int>> inside(seg.layers.size());
  for (const int s : segments) {
    if (s < 0 || static_cast<std::size_t>(s) >= seg.segments.size()) {
      throw std::invalid_argument("segmentIndicatorField: no segment " + std::to_string(s));
    }
    const SegmentInfo& info = seg.segments[static_cast<std::size_t>(s)];
    if (static_cast<std::size_t>(info.layer) >= seg.layers.size()) {
      throw std::invalid_argument("segmentIndicatorField: segment \"" + info.name + "\" has no layer");
    }
    inside[static_cast<std::size_t>(info.layer)].insert(info.label_value);
  }
  const haptics::VolumeGeometry& g = seg.layers.front()->geometry();
  const int pad = static_cast<int>(std::ceil(3.0 * sigma_voxels)) + 1;
  const std::array<int, 3> dims{g.dims[0] + 2 * pad, g.dims[1] + 2 * pad, g.dims[2] + 2 * pad};

  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(dims[0], dims[1], dims[2]);
  auto values = vtkSmartPointer<vtkFloatArray>::New();
  values->SetNumberOfTuples(static_cast<vtkIdType>(dims[0]) * dims[1] * dims[2]);
  values->Fill(0.0);
  float* v = values->GetPointer(0);
  for (int k = 0; k < g.dims[2]; ++k) {
    for (int j = 0; j < g.dims[1]; ++j) {
      for (int i = 0; i < g.dims[0]; ++i) {
        bool in = false;
        for (std::size_t l = 0; l < seg.layers.size() && !in; ++l) {
          if (!inside[l].empty()) in = inside[l].count(seg.label(static_cast<int>(l), i, j, k)) != 0;
        }
        if (in) {
          v[static_cast<std::size_t>(i + pad) +
            static_cast<std::size_t>(dims[0]) *
                (static_cast<std::size_t>(j + pad) + static_cast<std::size_t>(dims[1]) * static_cast<std::size_t>(k + pad))] =
              1.0f;
        }
      }
    }
  }
  image->GetPointData()->SetScalars(values);

  vtkImageData* smoothed = image;
  auto smooth = vtkSmartPointer<vtkImageGaussianSmooth>::New();
  if (sigma_voxels > 0.0) {
    smooth->SetInputData(image);
    smooth->SetDimensionality(3);
    smooth->SetStandardDeviations(sigma_voxels, sigma_voxels, sigma_voxels);  // pixel units
    smooth->SetRadiusFactors(3.0, 3.0, 3.0);                                  // kernel to 3 sigma
    smooth->Update();
    smoothed = smooth->GetOutput();
  }
  vtkDataArray* out = smoothed->GetPointData()->GetScalars();
  std::vector<std::uint8_t> voxels(static_cast<std::size_t>(out->GetNumberOfTuples()));
  for (std::size_t n = 0; n < voxels.size(); ++n) {
    const double f = std::clamp(out->GetComponent(static_cast<vtkIdType>(n), 0), 0.0, 1.0);
    voxels[n] = static_cast<std::uint8_t>(std::lround(255.0 * f));
  }
  haptics::VolumeGeometry padded = g;
  padded.dims = dims;
  padded.origin_W_m = g.origin_W_m - g.direction_W * (g.spacing_m * static_cast<double>(pad));
  return std::make_shared<const haptics::ScalarVolume>(
      haptics::ScalarVolume::FromVoxels(padded, voxels, 1.0 / 255.0, 0.0));
}

}  // namespace vh::io
