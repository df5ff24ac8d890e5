#pragma once
// Helpers shared by the GUI tests: event-loop waits and picture comparisons.

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <thread>
#include <vector>

#include <QApplication>
#include <QImage>

#include "vh/haptics/scalar_volume.h"
#include "vh/io/segmentation.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/segments.h"

namespace vh::ui::test {

inline const std::filesystem::path kSharedData = std::filesystem::path(VH_SHARED_DATASETS_DIR);
inline const std::filesystem::path kHead = kSharedData / "ct/ct-head-small";

/// The built-in sphere (radius 20 mm in 64^3 voxels of 1 mm, F = 20 mm - r, isovalue 0) with the
/// built-in probe and a simulated device section; loaded once. The analytic oracle of the parts'
/// tests.
inline const runtime::LoadedScene& sphereProbeScene() {
  static const runtime::LoadedScene scene = [] {
    runtime::SceneSpec spec;
    spec.volume.path = "builtin:sphere";
    spec.tool.mesh = "builtin:probe";
    spec.device = runtime::DeviceSpec{};
    return runtime::loadScene(spec);
  }();
  return scene;
}

/// A segmentation on `scan`'s grid with one segment, "nodule" (red): the voxels within
/// `radius_m` of `centre_W` [m] (label 1).
inline io::LoadedSegmentation ballSegmentation(const haptics::ScalarVolume& scan, const Eigen::Vector3d& centre_W,
                                               double radius_m) {
  const haptics::VolumeGeometry& g = scan.geometry();
  std::vector<std::uint8_t> labels(g.voxelCount(), 0);
  std::size_t n = 0;
  std::size_t inside = 0;
  for (int k = 0; k < g.dims[2]; ++k) {
    for (int j = 0; j < g.dims[1]; ++j) {
      for (int i = 0; i < g.dims[0]; ++i, ++n) {
        const Eigen::Vector3d p_W = g.origin_W_m + g.direction_W * Eigen::Vector3d(i, j, k).cwiseProduct(g.spacing_m);
        if ((p_W - centre_W).norm() <= radius_m) {
          labels[n] = 1;
          ++inside;
        }
      }
    }
  }
  io::LoadedSegmentation seg;
  seg.source = "in-memory";
  io::SegmentInfo info;
  info.id = "Segment_1";
  info.name = "nodule";
  info.color_rgb = {0.9, 0.3, 0.2};
  info.label_value = 1;
  info.voxel_count = inside;
  seg.segments.push_back(info);
  seg.layers.push_back(std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(g, labels)));
  return seg;
}

/// How much longer waits may take in a sanitizer build (VH_SANITIZE): ThreadSanitizer runs
/// the loads and renders about 5 to 15 times slower, AddressSanitizer about 2 to 3 times.
#if defined(__SANITIZE_THREAD__)
inline constexpr int kSanitizerSlowdown = 15;
#elif defined(__SANITIZE_ADDRESS__)
inline constexpr int kSanitizerSlowdown = 3;
#else
inline constexpr int kSanitizerSlowdown = 1;
#endif

/// Processes events until `done` or the timeout (times kSanitizerSlowdown); @return done().
inline bool waitFor(const std::function<bool()>& done, int timeout_ms) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms) * kSanitizerSlowdown;
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) {
      return false;
    }
    QApplication::processEvents(QEventLoop::AllEvents, 10);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

/// Processes events for `ms` milliseconds.
inline void pump(int ms) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  while (std::chrono::steady_clock::now() < end) {
    QApplication::processEvents(QEventLoop::AllEvents, 10);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

/// Fraction of pixels whose colour differs by more than `threshold` in some channel.
inline double differingFraction(const QImage& a, const QImage& b, int threshold = 24) {
  if (a.size() != b.size() || a.isNull()) {
    return 1.0;
  }
  const QImage ra = a.convertToFormat(QImage::Format_RGB32);
  const QImage rb = b.convertToFormat(QImage::Format_RGB32);
  std::size_t differing = 0;
  for (int y = 0; y < ra.height(); ++y) {
    const auto* pa = reinterpret_cast<const QRgb*>(ra.constScanLine(y));
    const auto* pb = reinterpret_cast<const QRgb*>(rb.constScanLine(y));
    for (int x = 0; x < ra.width(); ++x) {
      if (std::abs(qRed(pa[x]) - qRed(pb[x])) > threshold ||
          std::abs(qGreen(pa[x]) - qGreen(pb[x])) > threshold ||
          std::abs(qBlue(pa[x]) - qBlue(pb[x])) > threshold) {
        ++differing;
      }
    }
  }
  return static_cast<double>(differing) / (static_cast<double>(ra.width()) * ra.height());
}

/// Fraction of pixels brighter than the background gradient (grey level > 100).
inline double brightFraction(const QImage& image) {
  const QImage rgb = image.convertToFormat(QImage::Format_RGB32);
  std::size_t bright = 0;
  for (int y = 0; y < rgb.height(); ++y) {
    const auto* p = reinterpret_cast<const QRgb*>(rgb.constScanLine(y));
    for (int x = 0; x < rgb.width(); ++x) {
      bright += qGray(p[x]) > 100 ? 1 : 0;
    }
  }
  return static_cast<double>(bright) / (static_cast<double>(rgb.width()) * rgb.height());
}

}  // namespace vh::ui::test
