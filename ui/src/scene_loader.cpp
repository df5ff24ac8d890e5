#include "vh/ui/scene_loader.h"

#include <algorithm>
#include <exception>
#include <vector>

#include <QMetaObject>

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
  qRegisterMetaType<std::shared_ptr<vh::ui::LoadedViewerScene>>();
  qRegisterMetaType<std::shared_ptr<std::vector<vh::io::DicomSeriesInfo>>>();
  qRegisterMetaType<std::shared_ptr<vh::ui::RebuiltTool>>();
}

SceneLoader::~SceneLoader() {
  if (cancel_flag_) cancel_flag_->store(true);
  ++job_;  // nothing more is delivered
  joinWorkers(/*all=*/true);
}

void SceneLoader::start(std::function<void(const std::atomic<bool>&, std::uint64_t)> job) {
  if (busy_) cancel();
  joinWorkers(/*all=*/false);
  cancel_flag_ = std::make_shared<std::atomic<bool>>(false);
  const std::uint64_t id = ++job_;
  busy_ = true;
  auto done = std::make_shared<std::atomic<bool>>(false);
  workers_.push_back({std::thread([job = std::move(job), flag = cancel_flag_, id, done] {
                        job(*flag, id);
                        done->store(true, std::memory_order_release);
                      }),
                      done});
}

void SceneLoader::post(std::uint64_t job, std::function<void()> deliver) {
  // The loader outlives its workers (its destructor joins them), so `this` is valid here; the
  // job id check on the GUI thread drops results of cancelled jobs.
  {
    const std::lock_guard<std::mutex> lock(inbox_mutex_);
    inbox_.emplace_back(job, std::move(deliver));
  }
  QMetaObject::invokeMethod(this, "drain", Qt::QueuedConnection);
}

void SceneLoader::drain() {
  std::deque<std::pair<std::uint64_t, std::function<void()>>> items;
  {
    const std::lock_guard<std::mutex> lock(inbox_mutex_);
    items.swap(inbox_);
  }
  for (auto& [job, deliver] : items) {
    if (job == job_) deliver();
  }
}

void SceneLoader::joinWorkers(bool all) {
  for (auto it = workers_.begin(); it != workers_.end();) {
    if (all || it->done->load(std::memory_order_acquire)) {
      it->thread.join();
      it = workers_.erase(it);
    } else {
      ++it;
    }
  }
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

void SceneLoader::waitForIdle() { joinWorkers(/*all=*/true); }

void SceneLoader::loadScene(const runtime::SceneSpec& spec, const fs::path& opened,
                            std::optional<io::LoadedVolume> preloaded) {
  SceneLoadFunction load = load_scene_ ? load_scene_ : SceneLoadFunction(&loadSceneDefault);
  if (preloaded.has_value()) {
    load = [volume = std::move(*preloaded)](const runtime::SceneSpec& s, const std::function<void(double)>&,
                                            const std::atomic<bool>*) { return runtime::loadScene(s, volume); };
  }
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
