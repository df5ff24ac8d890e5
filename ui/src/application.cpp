#include "vh/ui/application.h"

#include <exception>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <QApplication>
#include <QImage>
#include <QLabel>
#include <QMessageBox>
#include <QMetaObject>
#include <QProgressBar>
#include <QSurfaceFormat>
#include <QTimer>
#include <QVBoxLayout>

#include <vtkImageData.h>

#include "vh/runtime/device.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/scene.h"
#include "vh/ui/main_window.h"
#include "vh/ui/vtk_view.h"

namespace vh::ui {
namespace {

/// The default surface format VTK needs; must be set before the QApplication exists.
void setDefaultSurfaceFormat() {
  QSurfaceFormat format;
  format.setRenderableType(QSurfaceFormat::OpenGL);
  format.setVersion(3, 2);
  format.setProfile(QSurfaceFormat::CoreProfile);
  format.setSwapBehavior(QSurfaceFormat::DoubleBuffer);
  format.setRedBufferSize(8);
  format.setGreenBufferSize(8);
  format.setBlueBufferSize(8);
  format.setAlphaBufferSize(8);
  format.setDepthBufferSize(24);
  format.setStencilBufferSize(8);
  format.setSamples(0);
  QSurfaceFormat::setDefaultFormat(format);
}

/// What the loader thread hands to the GUI thread.
struct LoadResult {
  std::optional<runtime::LoadedScene> scene;
  std::shared_ptr<runtime::Device> device;
  std::unique_ptr<runtime::HapticThread> haptics;
  std::string error;  // non-empty: the load failed
};

std::string sceneName(const runtime::SceneSpec& spec) {
  if (!spec.source.empty()) {
    return spec.source.string();
  }
  return spec.volume.path;
}

/// Runs on the loader thread: everything that reads files or builds the haptic model.
void loadInBackground(const runtime::SceneSpec& spec, LoadResult& out) {
  try {
    runtime::LoadedScene loaded = runtime::loadScene(spec);
    if (spec.device.has_value()) {
      out.device = loaded.makeDevice();
      if (out.device != nullptr) {
        out.haptics = loaded.makeHapticThread(out.device);
      }
    }
    out.scene = std::move(loaded);
  } catch (const std::exception& e) {
    out.error = e.what();
  } catch (...) {
    out.error = sceneName(spec) + ": unknown error while loading";
  }
}

/// Fraction of the image's pixels brighter than the view's background gradient (which stays
/// below ~0.31 in every channel): a cheap check that a screenshot shows something.
double brightFraction(const QImage& image) {
  if (image.isNull()) {
    return 0.0;
  }
  const QImage rgb = image.convertToFormat(QImage::Format_RGB32);
  std::size_t bright = 0;
  for (int y = 0; y < rgb.height(); ++y) {
    const auto* row = reinterpret_cast<const QRgb*>(rgb.constScanLine(y));
    for (int x = 0; x < rgb.width(); ++x) {
      if (qGray(row[x]) > 100) {
        ++bright;
      }
    }
  }
  return static_cast<double>(bright) / (static_cast<double>(rgb.width()) * rgb.height());
}

void reportError(const QString& title, const std::string& message, bool interactive) {
  std::cerr << "volume-haptics: " << message << '\n';
  if (interactive) {
    QMessageBox::critical(nullptr, title, QString::fromStdString(message));
  }
}

}  // namespace

int runApplication(int argc, char** argv, const runtime::SceneSpec& scene,
                   const AppOptions& options) {
  setDefaultSurfaceFormat();
  QApplication app(argc, argv);
  QApplication::setApplicationName("VolumeHaptics");
  // A scripted screenshot run must never wait on a modal dialog.
  const bool interactive = options.screenshot.empty();

  runtime::SceneSpec spec = scene;
  if (options.isovalue.has_value()) {
    spec.volume.isovalue = *options.isovalue;
    spec.volume.isovalue_set = true;
  }

  // A small window while the scene loads on another thread, so the GUI never freezes.
  QWidget loading;
  loading.setWindowTitle("VolumeHaptics");
  {
    auto* layout = new QVBoxLayout(&loading);
    auto* label = new QLabel(QString::fromStdString("Loading " + sceneName(spec) + " ..."), &loading);
    auto* bar = new QProgressBar(&loading);
    bar->setRange(0, 0);  // busy indicator
    layout->addWidget(label);
    layout->addWidget(bar);
  }
  loading.resize(420, 90);
  loading.show();

  std::unique_ptr<MainWindow> window;
  LoadResult result;
  int screenshot_status = 0;

  auto onLoaded = [&] {
    if (!result.error.empty() || !result.scene.has_value()) {
      loading.hide();
      reportError("VolumeHaptics: cannot load the scene",
                  result.error.empty() ? sceneName(spec) + ": nothing loaded" : result.error,
                  interactive);
      QApplication::exit(1);
      return;
    }
    try {
      runtime::LoadedScene& loaded = *result.scene;
      ViewerScene viewer;
      viewer.volume = loaded.volume;
      viewer.tool = loaded.tool;
      viewer.isovalue = loaded.isovalue;
      viewer.X_WT_initial = loaded.X_WT_initial;
      viewer.device = result.device;
      viewer.haptics = std::move(result.haptics);
      viewer.title = loaded.volume.info.source.filename().string();
      if (viewer.title.empty()) {
        viewer.title = spec.volume.path;
      }
      window = std::make_unique<MainWindow>(std::move(viewer));
      window->resize(options.window_width, options.window_height);
      window->show();
      loading.hide();
      window->startHaptics();
      if (options.device_pose.has_value()) {
        window->setDevicePose(*options.device_pose);
      } else if (options.touch) {
        if (!window->touchSurface(options.touch_depth_m)) {
          std::cerr << "volume-haptics: touch: no simulated device, or no surface towards the "
                       "volume's centre\n";
        }
      }
    } catch (const std::exception& e) {
      window.reset();
      loading.hide();
      reportError("VolumeHaptics: cannot show the scene", sceneName(spec) + ": " + e.what(),
                  interactive);
      QApplication::exit(1);
      return;
    }

    if (!options.screenshot.empty()) {
      QTimer::singleShot(std::max(0, options.screenshot_delay_ms), window.get(), [&] {
        window->refreshFromHaptics(/*update_status_now=*/true);
        window->renderStill(/*best_quality=*/true);
        // QWidget::grab() renders the GL view (paintGL) and composites it with the widgets.
        const QImage shot = window->grab().toImage();
        const QRect view_rect(window->view()->mapTo(window.get(), QPoint(0, 0)),
                              window->view()->size());
        const double bright = brightFraction(shot.copy(view_rect));
        if (bright < 0.005) {
          std::cerr << "volume-haptics: screenshot: the view looks empty (" << bright * 100.0
                    << "% non-background pixels)\n";
        }
        const QString path = QString::fromStdString(options.screenshot.string());
        if (!shot.save(path, "PNG")) {
          std::cerr << "volume-haptics: screenshot: cannot write " << options.screenshot.string()
                    << '\n';
          screenshot_status = 1;
        } else {
          std::cout << "Screenshot saved: " << options.screenshot.string() << " ("
                    << shot.width() << " x " << shot.height() << ", status: "
                    << window->statusText().toStdString() << ")\n";
        }
        window->stopHaptics();
        QApplication::exit(screenshot_status);
      });
    }
  };

  std::thread loader([&] {
    loadInBackground(spec, result);
    QMetaObject::invokeMethod(&app, onLoaded, Qt::QueuedConnection);
  });

  const int code = QApplication::exec();
  loader.join();
  if (window != nullptr) {
    window->stopHaptics();
    window.reset();  // VTK objects go while the application still exists
  }
  return code;
}

}  // namespace vh::ui
