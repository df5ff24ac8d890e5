#include "vh/ui/scene_loader.h"

#include <algorithm>
#include <exception>

#include <QMetaObject>
#include <QPointer>

#include "vh/runtime/device.h"
#include "vh/runtime/haptic_thread.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

QString q(const std::string& s) { return QString::fromStdString(s); }
QString q(const fs::path& p) { return QString::fromStdString(p.string()); }

std::string displayName(const runtime::SceneSpec& spec, const fs::path& opened) {
  if (!spec.source.empty()) return spec.source.filename().string();
  if (!opened.empty()) return opened.filename().empty() ? opened.parent_path().filename().string()
                                                       : opened.filename().string();
  return spec.volume.path;
}

}  // namespace

runtime::LoadedScene loadSceneDefault(const runtime::SceneSpec& spec, const std::function<void(double)>& progress,
                                      const std::atomic<bool>* cancel) {
  return runtime::loadScene(spec, progress, cancel);
}

void SceneLoader::setSceneLoadFunction(SceneLoadFunction load) { load_scene_ = std::move(load); }

SceneLoader::SceneLoader(QObject* parent) : QObject(parent) {
  // Two threads: a cancelled job may still be finishing while the next one starts.
  pool_.setMaxThreadCount(2);
  qRegisterMetaType<std::shared_ptr<vh::ui::LoadedViewerScene>>();
  qRegisterMetaType<std::shared_ptr<std::vector<vh::io::DicomSeriesInfo>>>();
  qRegisterMetaType<std::shared_ptr<vh::ui::RebuiltTool>>();
}

SceneLoader::~SceneLoader() {
  if (cancel_flag_) cancel_flag_->store(true);
  ++job_;  // nothing more is delivered
  pool_.waitForDone();
}

void SceneLoader::start(std::function<void(const std::atomic<bool>&, std::uint64_t)> job) {
  if (busy_) cancel();
  cancel_flag_ = std::make_shared<std::atomic<bool>>(false);
  const std::uint64_t id = ++job_;
  busy_ = true;
  auto flag = cancel_flag_;
  pool_.start([job = std::move(job), flag, id] { job(*flag, id); });
}

void SceneLoader::post(std::uint64_t job, std::function<void()> deliver) {
  // The loader outlives its jobs (its destructor waits for the pool), so `this` is valid here;
  // the job id check on the GUI thread drops results of cancelled jobs.
  QMetaObject::invokeMethod(
      this,
      [this, job, deliver = std::move(deliver)] {
        if (job == job_) deliver();
      },
      Qt::QueuedConnection);
}

void SceneLoader::finish(std::uint64_t job) {
  if (job != job_) return;
  busy_ = false;
  emit idle();
}

void SceneLoader::cancel() {
  if (!busy_) return;
  if (cancel_flag_) cancel_flag_->store(true);
  ++job_;
  busy_ = false;
  emit cancelled();
  emit idle();
}

void SceneLoader::waitForIdle() { pool_.waitForDone(); }

void SceneLoader::loadScene(const runtime::SceneSpec& spec, const fs::path& opened) {
  const SceneLoadFunction load = load_scene_ ? load_scene_ : SceneLoadFunction(&loadSceneDefault);
  start([this, spec, opened, load](const std::atomic<bool>& cancel, std::uint64_t job) {
    const std::string name = displayName(spec, opened);
    auto stage = [&](const QString& text, int percent) {
      post(job, [this, text, percent] { emit progress(text, percent); });
    };
    auto result = std::make_shared<LoadedViewerScene>();
    try {
      const QString reading = QString("Reading %1").arg(q(name));
      stage(reading, -1);
      int shown = -1;  // worker: the last percent posted (one signal per percent, not per slice)
      const auto read_progress = [&](double fraction) {
        const int percent = static_cast<int>(std::clamp(fraction, 0.0, 1.0) * 70.0);
        if (percent == shown) return;
        shown = percent;
        stage(reading, percent);
      };
      result->scene = load(spec, read_progress, &cancel);
      if (cancel.load()) return;
      stage("Computing the histogram", 70);
      result->histogram = computeHistogram(result->scene.volume.image.get(), 256, &cancel);
      if (cancel.load()) return;
      stage("Opening the device", 85);
      // The device may take a while to open (hardware); the session builds the haptic threads.
      if (spec.device.has_value()) result->device = result->scene.makeDevice();
      if (cancel.load()) return;
      result->opened = opened;
      result->title = name;
      post(job, [this, result, job] {
        finish(job);
        emit sceneLoaded(result);
      });
    } catch (const io::LoadCancelled&) {
      return;  // cancel() has said so already
    } catch (const std::exception& e) {
      if (cancel.load()) return;  // a read stopped by the cancel, whatever it threw
      const QString what = q(name);
      const QString message = q(std::string(e.what()));
      post(job, [this, what, message, job] {
        finish(job);
        emit failed(what, message);
      });
    }
  });
}

void SceneLoader::listSeries(const fs::path& folder) {
  start([this, folder](const std::atomic<bool>& cancel, std::uint64_t job) {
    try {
      post(job, [this] { emit progress("Scanning the folder for DICOM series", -1); });
      auto series = std::make_shared<std::vector<io::DicomSeriesInfo>>(io::listDicomSeries(
          folder,
          [&](int done, int total) {
            if (total > 0) {
              const int percent = 10 + 90 * done / total;
              post(job, [this, percent] { emit progress("Reading the series' headers", percent); });
            }
          },
          &cancel));
      if (cancel.load()) return;
      const QString name = q(folder);
      post(job, [this, name, series, job] {
        finish(job);
        emit seriesListed(name, series);
      });
    } catch (const std::exception& e) {
      const QString what = q(folder);
      const QString message = q(std::string(e.what()));
      post(job, [this, what, message, job] {
        finish(job);
        emit failed(what, message);
      });
    }
  });
}

void SceneLoader::buildTool(int choice_index, const ToolChoice& choice, double point_spacing_m,
                            std::shared_ptr<const haptics::ScalarVolume> field, double isovalue) {
  start([this, choice_index, choice, point_spacing_m, field, isovalue](const std::atomic<bool>& cancel,
                                                                       std::uint64_t job) {
    try {
      post(job, [this, label = q(choice.label)] { emit progress(QString("Building the tool: %1").arg(label), -1); });
      auto result = std::make_shared<RebuiltTool>();
      result->choice_index = choice_index;
      result->built = ui::buildTool(choice, point_spacing_m, *field, isovalue);
      if (cancel.load()) return;
      post(job, [this, result, job] {
        finish(job);
        emit toolBuilt(result);
      });
    } catch (const std::exception& e) {
      const QString what = q(choice.label);
      const QString message = q(std::string(e.what()));
      post(job, [this, what, message, job] {
        finish(job);
        emit failed(what, message);
      });
    }
  });
}

}  // namespace vh::ui
