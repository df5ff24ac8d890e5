#include "vh/ui/application.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <QApplication>
#include <QImage>
#include <QSettings>
#include <QSurfaceFormat>
#include <QTimer>

#include "vh/runtime/scene.h"
#include "vh/ui/panels/igtl_panel.h"
#include "vh/ui/main_window.h"
#include "vh/ui/preferences.h"
#include "vh/ui/scene_opener.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/view_controller.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {

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

namespace {

namespace fs = std::filesystem;

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

/// The command line's window settings: size, saved layout (not in a scripted run), render mode,
/// preset, and an OpenIGTLink server, which wins over the scene's and listens from now on.
/// @return false (the error printed) when the server cannot start.
bool applyWindowOptions(MainWindow& window, runtime::SceneSpec& spec, const AppOptions& options, bool scripted) {
  window.setInteractive(!scripted);
  window.resize(options.window_width, options.window_height);
  if (!scripted) window.restoreLayout();
  if (options.render_mode.has_value()) window.viewController()->setRenderMode(*options.render_mode);
  if (options.preset.has_value()) window.viewController()->setPreset(*options.preset);
  if (options.igtl_port.has_value()) {
    // The command line's server wins over a scene file's "openigtlink" section; it listens from
    // now on, before the scene has loaded.
    spec.openigtlink = runtime::OpenIgtlinkSpec{*options.igtl_port, options.igtl_rate_Hz};
    QString error;
    if (!window.igtlPanel()->apply(
            {true, *options.igtl_port, options.igtl_rate_Hz, options.igtl_bind, options.igtl_allow}, &error)) {
      std::cerr << "volume-haptics: error: " << error.toStdString() << std::endl;
      return false;
    }
  }
  return true;
}

/// --touch: the simulated device moves onto the surface `depth_m` deep along the view through the
/// volume's centre; `touch_pending` stays set until the placement has reached the haptic threads,
/// the proxy rests on the surface and the view has framed the contact.
void touchSurfaceAndFrame(MainWindow* window, double depth_m, bool& touch_pending) {
  if (!window->deviceInput()->touchSurface(depth_m)) {
    std::cerr << "volume-haptics: touch: no simulated device, or no surface along the view "
                 "through the volume's centre\n";
    return;
  }
  // Frame the contact once the placement has reached the haptic threads and the proxy
  // rests on the surface.
  touch_pending = true;
  auto* arrival = new QTimer(window);
  arrival->setInterval(50);
  QObject::connect(arrival, &QTimer::timeout, window, [window, &touch_pending, arrival] {
    if (window->deviceInput()->touchInProgress()) return;
    arrival->stop();
    arrival->deleteLater();
    QTimer::singleShot(300, window, [window, &touch_pending] {
      window->viewController()->refresh(true);
      window->viewController()->focusOnTool();
      touch_pending = false;
    });
  });
  arrival->start();
}

/// The screenshot (--screenshot): the widgets with the view's frame rendered into its place
/// (QWidget::grab() alone leaves the view's native window blank), a warning when the view looks
/// empty. @return 0, or 1 when the file cannot be written.
int saveScreenshot(MainWindow& window, const fs::path& file) {
  window.viewController()->refresh(/*update_status_now=*/true);
  window.sceneView()->renderStill(/*best_quality=*/true);
  const QImage shot = grabWithView(window, *window.sceneView()->widget());
  const QRect view_rect(window.sceneView()->widget()->mapTo(&window, QPoint(0, 0)), window.sceneView()->widget()->size());
  const double bright = brightFraction(shot.copy(view_rect));
  if (bright < 0.005) {
    std::cerr << "volume-haptics: screenshot: the view looks empty (" << bright * 100.0
              << "% non-background pixels)\n";
  }
  const QString path = QString::fromStdString(file.string());
  if (!shot.save(path, "PNG")) {
    std::cerr << "volume-haptics: screenshot: cannot write " << file.string() << '\n';
    return 1;
  }
  std::cout << "Screenshot saved: " << file.string() << " (" << shot.width() << " x "
            << shot.height() << ", status: " << window.statusText().toStdString() << ")\n";
  return 0;
}

/// Opens the scene the command line gives: a folder given on its own (no --series, --phase or
/// --isovalue) through the series chooser, a session recording (.vhrec) in replay, everything
/// else as given.
void openStartScene(MainWindow& window, const runtime::SceneSpec& spec, const AppOptions& options) {
  std::error_code ec;
  const fs::path volume_path(spec.volume.path);
  const bool plain_folder = spec.source.empty() && !options.isovalue.has_value() && spec.volume.series.empty() &&
                            spec.volume.phase == 0 && spec.volume.path.rfind("builtin:", 0) != 0 &&
                            fs::is_directory(volume_path, ec);
  // A session recording (.vhrec) opens in replay (MainWindow::openPath()).
  const bool recording = spec.source.empty() && volume_path.extension() == ".vhrec";
  if (plain_folder || recording) {
    window.openPath(QString::fromStdString(volume_path.string()));
  } else {
    fs::path opened = spec.source;
    if (opened.empty() && spec.volume.path.rfind("builtin:", 0) != 0) opened = volume_path;
    window.opener()->openScene(spec, opened);
  }
}

/// The CPU time stolen from this machine so far [ms]: /proc/stat's "cpu" line, its 8th value
/// (steal, in USER_HZ ticks), the time the hypervisor ran other guests on this VM's vCPUs. NaN
/// where the kernel does not say.
double stolenCpuMs() {
  std::ifstream in("/proc/stat");
  std::string cpu;
  unsigned long long v[8] = {};
  if (!(in >> cpu) || cpu != "cpu") return std::numeric_limits<double>::quiet_NaN();
  for (unsigned long long& x : v)
    if (!(in >> x)) return std::numeric_limits<double>::quiet_NaN();
  return 1e3 * static_cast<double>(v[7]) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

/// AppOptions::servo_log: a line a second from the GUI thread (the haptic snapshot is read
/// without blocking the threads). @return false (with a message) when the file cannot be written.
bool startServoLog(MainWindow& window, const fs::path& path) {
  auto out = std::make_shared<std::ofstream>(path, std::ios::app);
  if (!*out) {
    std::cerr << "volume-haptics: --servo-log: cannot write " << path.string() << "\n";
    return false;
  }
  struct Last {
    std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
    double steal_ms = stolenCpuMs();
    std::uint64_t frames = 0, coupling_misses = 0, solver_misses = 0, ticks = 0;
  };
  auto last = std::make_shared<Last>();
  auto* timer = new QTimer(&window);
  QObject::connect(timer, &QTimer::timeout, &window, [&window, out, last] {
    nlohmann::ordered_json line;
    line["t_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - last->t0).count();
    const double steal_ms = stolenCpuMs();
    line["steal_ms"] = std::isfinite(steal_ms - last->steal_ms) ? nlohmann::json(steal_ms - last->steal_ms) : nlohmann::json();
    last->steal_ms = steal_ms;
    const std::uint64_t frames = window.sceneView()->widget()->frameCount();
    line["frames"] = frames - last->frames;
    last->frames = frames;
    runtime::HapticSnapshot s;
    if (window.session().hapticsRunning() && window.session().latestSnapshot(s)) {
      const bool restarted = s.coupling.ticks < last->ticks;  // new threads count from zero
      const auto thread = [&](const runtime::ThreadTiming& t, std::uint64_t& misses) {
        nlohmann::ordered_json j;
        j["rate_Hz"] = t.rate_Hz;
        j["max_tick_us"] = t.max_tick_us;
        j["jitter_us"] = t.jitter_us;
        j["misses"] = restarted ? t.deadline_misses : t.deadline_misses - std::min(misses, t.deadline_misses);
        misses = t.deadline_misses;
        return j;
      };
      line["coupling"] = thread(s.coupling, last->coupling_misses);
      line["solver"] = thread(s.solver, last->solver_misses);
      line["realtime"] = window.session().hapticThread()->realtimeScheduling();
      last->ticks = s.coupling.ticks;
    } else {
      line["haptics"] = false;
    }
    *out << line.dump() << '\n';
    out->flush();
  });
  timer->start(1000);
  return true;
}

}  // namespace

int runApplication(int argc, char** argv, const runtime::SceneSpec& scene, const AppOptions& options) {
  setDefaultSurfaceFormat();
  QApplication app(argc, argv);
  QApplication::setApplicationName("VolumeHaptics");
  QApplication::setOrganizationName("VolumeHaptics");
  QApplication::setApplicationVersion(VH_VERSION_STRING);
  makeSettingsPrivate();  // it lists recent scans' paths
  // A scripted screenshot run must never wait on a modal dialog.
  const bool scripted = !options.screenshot.empty();

  runtime::SceneSpec spec = scene;
  if (options.isovalue.has_value()) {
    spec.volume.isovalue = *options.isovalue;
    spec.volume.isovalue_set = true;
  }

  auto window = std::make_unique<MainWindow>();
  if (!applyWindowOptions(*window, spec, options, scripted)) return 1;
  // An unwritable log ends the program before its window shows.
  if (!options.servo_log.empty() && !startServoLog(*window, options.servo_log)) return 1;
  window->show();

  bool loaded_once = false;
  int screenshot_status = 0;
  bool touch_pending = false;  // --touch: the device is on its way and the view not yet on it
  std::function<void()> shoot;
  QObject::connect(window.get(), &MainWindow::loadFailed, window.get(), [&](const QString&) {
    if (scripted && !loaded_once) QApplication::exit(1);
  });
  QObject::connect(window.get(), &MainWindow::sceneLoaded, window.get(), [&] {
    if (loaded_once) return;  // scripting applies to the first scene only
    loaded_once = true;
    if (options.device_pose.has_value()) {
      window->deviceInput()->setDevicePose(*options.device_pose);
    } else if (options.touch) {
      touchSurfaceAndFrame(window.get(), options.touch_depth_m, touch_pending);
    }
    if (!scripted) return;
    // The screenshot after the delay, and after a --touch has arrived and been framed.
    shoot = [&] {
      if (touch_pending) {
        QTimer::singleShot(100, window.get(), shoot);
        return;
      }
      screenshot_status = saveScreenshot(*window, options.screenshot);
      window->session().stopHaptics();
      QApplication::exit(screenshot_status);
    };
    QTimer::singleShot(std::max(0, options.screenshot_delay_ms), window.get(), shoot);
  });
  openStartScene(*window, spec, options);

  const int code = QApplication::exec();
  window->session().stopHaptics();
  window.reset();  // VTK objects go while the application still exists
  return code;
}

}  // namespace vh::ui
