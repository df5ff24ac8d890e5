// What an MR and a PET scan show when they open: the isosurface at the default isovalue
// (runtime::defaultIsovalue(): the triangle threshold for MR and PET) must show the anatomy, a
// body, not a speckle cloud or two floating blobs. Rendered in the main view (320 x 240) under
// Xvfb, as the window renders them. The oracle is the picture itself: the pixels that differ
// from the same view with nothing on it (isovalue above the maximum), their area and their
// 4-connected components; the middle of the range (the old default) is measured beside it.
//
// MR: the shared MR head (../shared/datasets/nrrd/mr-brain/brain1_image.nrrd; skipped with a
// message when absent), its modality set to MR as a DICOM MR's would be. PET: no PET is among
// the shared datasets, so a whole-body PET in SUV is written here: a body of uptake about 1 with
// noise, a brain (8), a bladder (20) and a lesion (12) in a background of about 0.05.
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include <QImage>
#include <QVBoxLayout>
#include <QWidget>

#include <gtest/gtest.h>
#include <vtkActor.h>

#include "ui_test_util.h"
#include "vh/runtime/default_isovalue.h"
#include "vh/runtime/scene.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

/// The picture's foreground: area fraction and connected components.
struct Coverage {
  double area = 0.0;              ///< Foreground pixels over all pixels.
  int components = 0;             ///< 4-connected components of at least kMinComponent pixels.
  double largest = 0.0;           ///< The largest component over the foreground.
};

constexpr int kMinComponent = 20;  // px: smaller specks are not counted as parts

/// Foreground: pixels of `frame` that differ from `empty` by more than 24 in a channel.
Coverage coverageOf(const QImage& frame, const QImage& empty) {
  const QImage a = frame.convertToFormat(QImage::Format_RGB32);
  const QImage b = empty.convertToFormat(QImage::Format_RGB32);
  const int w = a.width(), h = a.height();
  std::vector<std::uint8_t> fg(static_cast<std::size_t>(w) * h, 0);
  std::size_t n = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const QRgb p = a.pixel(x, y), q = b.pixel(x, y);
      const int d = std::max({std::abs(qRed(p) - qRed(q)), std::abs(qGreen(p) - qGreen(q)), std::abs(qBlue(p) - qBlue(q))});
      if (d > 24) {
        fg[static_cast<std::size_t>(y) * w + x] = 1;
        ++n;
      }
    }
  }
  Coverage c;
  c.area = static_cast<double>(n) / (static_cast<double>(w) * h);
  std::vector<int> stack;
  std::size_t largest = 0;
  for (std::size_t start = 0; start < fg.size(); ++start) {
    if (fg[start] != 1) continue;
    std::size_t size = 0;
    stack.assign(1, static_cast<int>(start));
    fg[start] = 2;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      ++size;
      const int x = i % w, y = i / w;
      for (const int j : {x > 0 ? i - 1 : -1, x + 1 < w ? i + 1 : -1, y > 0 ? i - w : -1, y + 1 < h ? i + w : -1}) {
        if (j >= 0 && fg[static_cast<std::size_t>(j)] == 1) {
          fg[static_cast<std::size_t>(j)] = 2;
          stack.push_back(j);
        }
      }
    }
    if (size >= static_cast<std::size_t>(kMinComponent)) ++c.components;
    largest = std::max(largest, size);
  }
  c.largest = n > 0 ? static_cast<double>(largest) / n : 0.0;
  return c;
}

/// `scene` shown in a 320 x 240 view as the window opens it (camera reset, isosurface), its
/// picture at `isovalue` measured against the empty view.
Coverage coverageAt(const runtime::LoadedScene& scene, double isovalue, const std::string& name) {
  QWidget host;
  auto* layout = new QVBoxLayout(&host);
  layout->setContentsMargins(0, 0, 0, 0);
  auto* view = new SceneView(&host);
  layout->addWidget(view->widget());
  host.resize(320, 240);
  host.show();
  test::pump(50);
  runtime::LiveValues live = runtime::LiveValues::initial(scene);
  ViewLook look;
  look.mode = RenderMode::kIsosurface;
  view->setScene(sceneActorsSpecFor(scene, live), scene.X_WT_initial, look);
  view->setMarkerVisible(false);
  view->actors().proxyActor()->SetVisibility(false);
  view->actors().deviceActor()->SetVisibility(false);
  const auto still = [&](double s) {
    view->setIsovalue(s);
    view->renderStill(true);
    test::pump(100);
    // Best quality again for the frame grabbed: a still frame drawn meanwhile that took longer
    // than SceneActors' kStillSlowMs (3 s, a busy machine) steps the next still frames down.
    view->renderStill(true);
    return view->widget()->grabFrame();
  };
  const QImage empty = still(scene.volume.field->maxValue() * 2.0 + 1.0);
  const QImage frame = still(isovalue);
  fs::create_directories("default-views");
  frame.save(QString::fromStdString("default-views/" + name + ".png"));
  const Coverage c = coverageOf(frame, empty);
  std::cout << "[ " << name << " ] isovalue " << isovalue << ": area " << 100.0 * c.area << " %, " << c.components
            << " components of >= " << kMinComponent << " px, the largest " << 100.0 * c.largest
            << " % of the area" << std::endl;
  return c;
}

/// A whole-body PET in SUV (see the file comment): 48 x 36 x 160 voxels of 10 x 10 x 12 mm,
/// float, loaded through the NRRD reader, modality PT, unit SUVbw.
runtime::LoadedScene wholeBodyPet() {
  const fs::path file = fs::temp_directory_path() / ("vh_pet_" + std::to_string(::getpid()) + ".nrrd");
  const int nx = 48, ny = 36, nz = 160;
  {
    std::ofstream out(file, std::ios::binary);
    out << "NRRD0004\ntype: float\ndimension: 3\nspace: left-posterior-superior\nsizes: " << nx << " " << ny << " " << nz
        << "\nspace directions: (10,0,0) (0,10,0) (0,0,12)\nspace origin: (-235,-175,-1900)\nendian: little\n"
        << "encoding: raw\n\n";
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::vector<float> voxels;
    for (int k = 0; k < nz; ++k) {
      for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) {
          const double x = -235.0 + 10.0 * i, y = -175.0 + 10.0 * j, z = -1900.0 + 12.0 * k;  // mm
          // Body: an elliptic trunk from the feet (z -1880) to the neck (z -350), a head above.
          const bool trunk = z > -1880.0 && z < -350.0 && (x / 180.0) * (x / 180.0) + (y / 110.0) * (y / 110.0) <= 1.0;
          const bool head = (x / 80.0) * (x / 80.0) + (y / 90.0) * (y / 90.0) + ((z + 230.0) / 110.0) * ((z + 230.0) / 110.0) <= 1.0;
          double suv = 0.05 + 0.03 * noise(rng);
          if (trunk || head) suv = 1.0 + 0.25 * noise(rng);
          if (((x / 65.0) * (x / 65.0) + (y / 75.0) * (y / 75.0) + ((z + 210.0) / 80.0) * ((z + 210.0) / 80.0)) <= 1.0) {
            suv = 8.0 + noise(rng);  // brain
          }
          if ((x * x + (y - 20.0) * (y - 20.0) + (z + 1150.0) * (z + 1150.0)) <= 45.0 * 45.0) suv = 20.0 + noise(rng);  // bladder
          if (((x - 80.0) * (x - 80.0) + (y + 30.0) * (y + 30.0) + (z + 700.0) * (z + 700.0)) <= 25.0 * 25.0) {
            suv = 12.0 + noise(rng);  // lesion
          }
          voxels.push_back(static_cast<float>(std::max(0.0, suv)));
        }
      }
    }
    out.write(reinterpret_cast<const char*>(voxels.data()), static_cast<std::streamsize>(voxels.size() * sizeof(float)));
  }
  runtime::SceneSpec spec;
  spec.volume.path = file.string();
  spec.tool.mesh = "builtin:probe";
  runtime::LoadedScene scene = runtime::loadScene(spec);
  fs::remove(file);
  scene.volume.info.modality = "PT";
  scene.volume.info.value_unit = "SUVbw";
  scene.isovalue = runtime::defaultIsovalue(scene.volume);
  return scene;
}

TEST(DefaultView, AnMrHeadOpensAsAHeadNotASpeckleCloud) {
  const fs::path path = test::kSharedData / "nrrd" / "mr-brain" / "brain1_image.nrrd";
  if (!fs::exists(path)) GTEST_SKIP() << path << " is absent (the shared datasets, ../shared/datasets)";
  runtime::SceneSpec spec;
  spec.volume.path = path.string();
  spec.tool.mesh = "builtin:probe";
  runtime::LoadedScene scene = runtime::loadScene(spec);
  scene.volume.info.modality = "MR";  // a NRRD names no modality; a DICOM MR's would be MR
  scene.isovalue = runtime::defaultIsovalue(scene.volume);
  const haptics::ScalarVolume& f = *scene.volume.field;
  const double mid = 0.5 * (f.minValue() + f.maxValue());
  ASSERT_LT(scene.isovalue, mid) << "the triangle threshold lies below the middle of an MR's range";
  const Coverage at_default = coverageAt(scene, scene.isovalue, "mr-default");
  const Coverage at_mid = coverageAt(scene, mid, "mr-middle");
  // The head: one solid shape filling a good part of the view.
  EXPECT_GT(at_default.area, 0.15);
  EXPECT_LT(at_default.area, 0.85);
  EXPECT_LE(at_default.components, 3);
  EXPECT_GT(at_default.largest, 0.9);
  // The middle of the range showed much less of it.
  EXPECT_GT(at_default.area, 2.0 * at_mid.area);
}

TEST(DefaultView, AWholeBodyPetOpensAsABodyNotFloatingBlobs) {
  const runtime::LoadedScene scene = wholeBodyPet();
  const haptics::ScalarVolume& f = *scene.volume.field;
  const double mid = 0.5 * (f.minValue() + f.maxValue());
  std::cout << "[ pet ] SUV " << f.minValue() << ".." << f.maxValue() << ", default " << scene.isovalue << ", middle "
            << mid << std::endl;
  // The body (about 1) lies above the default, the background (about 0.05) below it.
  EXPECT_GT(scene.isovalue, 0.15);
  EXPECT_LT(scene.isovalue, 0.8);
  const Coverage at_default = coverageAt(scene, scene.isovalue, "pet-default");
  const Coverage at_mid = coverageAt(scene, mid, "pet-middle");
  // One body, head to feet in the view (the camera frames the whole volume: a long, narrow
  // shape in a wide view).
  EXPECT_GT(at_default.area, 0.04);
  EXPECT_LT(at_default.area, 0.6);
  EXPECT_LE(at_default.components, 2);
  EXPECT_GT(at_default.largest, 0.9);
  // The middle of the range: the hottest spot only, a small fraction of the body's area.
  EXPECT_LT(at_mid.area, 0.2 * at_default.area);
}

}  // namespace
}  // namespace vh::ui
