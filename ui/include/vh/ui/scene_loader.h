#pragma once
/// @file
/// Loading off the GUI thread: scenes (volume + tool + device + haptic thread + histogram),
/// DICOM folder listings and tool rebuilds run on a worker thread (a std::thread per job);
/// progress and the result come back to the GUI thread through a mutex-guarded inbox drained by
/// a queued call, so every hand-off between the threads is one ThreadSanitizer can see. One job at a time;
/// cancel() abandons the running job at once: its result is dropped when it arrives (a read
/// inside VTK cannot be interrupted, so the worker may run on briefly, never touching the
/// window; the stages in between check the cancel flag).

#include <atomic>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>
#include <functional>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <QObject>
#include <QString>

#include "vh/io/dicom_series.h"
#include "vh/runtime/scene.h"
#include "vh/ui/panels/histogram.h"
#include "vh/ui/tool_catalog.h"

namespace vh::ui {

/// What a scene load produces on the worker, handed to the GUI thread whole (the session
/// builds the haptic threads).
struct LoadedViewerScene {
  runtime::LoadedScene scene;                      ///< Volume, tool, isovalue, initial pose.
  Histogram histogram;                             ///< Of the volume's values (256 bins).
  std::shared_ptr<runtime::Device> device;         ///< Null when the scene has no device.
  std::filesystem::path opened;                    ///< What the user opened (file or folder).
  std::string title;                               ///< Window title detail.
};

/// Loads a scene on the worker: runtime::loadScene() with the volume read's `progress` (fraction
/// 0..1, called on the worker) and `cancel` (io::VolumeLoadOptions; a cancelled read throws
/// io::LoadCancelled).
using SceneLoadFunction = std::function<runtime::LoadedScene(
    const runtime::SceneSpec& spec, const std::function<void(double fraction)>& progress,
    const std::atomic<bool>* cancel)>;

/// The SceneLoadFunction used unless another is set: runtime::loadScene(spec). It cannot pass
/// `progress` and `cancel` on yet (runtime::loadScene takes neither), so the read shows a busy
/// indicator and a cancelled read runs on, its result dropped.
runtime::LoadedScene loadSceneDefault(const runtime::SceneSpec& spec,
                                      const std::function<void(double fraction)>& progress,
                                      const std::atomic<bool>* cancel);

/// A tool rebuilt for the current volume (haptics panel).
struct RebuiltTool {
  int choice_index = -1;  ///< Index into the tool catalog.
  BuiltTool built;        ///< Tool, spacing, free initial pose.
};

class SceneLoader : public QObject {
  Q_OBJECT

 public:
  explicit SceneLoader(QObject* parent = nullptr);
  ~SceneLoader() override;  ///< Cancels and waits for the worker.

  /// Loads `spec` (runtime::loadScene), opens its device, and computes the histogram.
  /// `opened` is remembered as what the user opened (recent files). Emits progress() (the read's
  /// fraction as 0..70 %), then sceneLoaded() or failed() (or cancelled()).
  /// `preloaded`: a volume already in memory (received over OpenIGTLink) replaces the read of
  /// spec.volume.path (runtime::loadScene(spec, preloaded)).
  void loadScene(const runtime::SceneSpec& spec, const std::filesystem::path& opened,
                 std::optional<io::LoadedVolume> preloaded = std::nullopt);
  /// Replaces how loadScene() loads (tests; a runtime that reports progress). Null: the default.
  void setSceneLoadFunction(SceneLoadFunction load);
  /// Lists the DICOM series in `folder`; emits seriesListed() or failed().
  void listSeries(const std::filesystem::path& folder);
  /// Builds `choice` at `point_spacing_m` (0: automatic) for `field` / `isovalue` (placed just
  /// clear of it). Emits toolBuilt() or failed().
  void buildTool(int choice_index, const ToolChoice& choice, double point_spacing_m,
                 std::shared_ptr<const haptics::ScalarVolume> field, double isovalue);

  /// Abandons the running job (no result signal but cancelled()).
  void cancel();
  bool busy() const noexcept { return busy_; }
  /// Blocks until the worker is idle (tests, shutdown).
  void waitForIdle();

 signals:
  /// `percent` in [0, 100], or -1 while the stage's length is unknown (a busy indicator).
  void progress(const QString& stage, int percent);
  void sceneLoaded(std::shared_ptr<vh::ui::LoadedViewerScene> scene);
  void seriesListed(const QString& folder, std::shared_ptr<std::vector<vh::io::DicomSeriesInfo>> series);
  void toolBuilt(std::shared_ptr<vh::ui::RebuiltTool> tool);
  /// `what`: the file, folder or tool concerned; `message`: the problem (names the file).
  void failed(const QString& what, const QString& message);
  void cancelled();
  /// After any of the above: the loader is idle.
  void idle();

 private:
  /// Runs `job(cancel_flag, job_id)` on a new worker thread as the current job.
  void start(std::function<void(const std::atomic<bool>& cancel, std::uint64_t job)> job);
  /// Worker side: runs `deliver` on the GUI thread if job `job` is still the current one.
  void post(std::uint64_t job, std::function<void()> deliver);
  /// GUI thread: runs what the workers posted (queued call from post()).
  Q_INVOKABLE void drain();
  /// GUI thread: the current job ended (result delivered).
  void finish(std::uint64_t job);
  /// GUI thread: joins the workers that are done (`all`: every worker, waiting for them).
  void joinWorkers(bool all);

  struct Worker {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;
  };
  std::vector<Worker> workers_;  // GUI thread; a cancelled job may still run beside the next
  std::mutex inbox_mutex_;
  std::deque<std::pair<std::uint64_t, std::function<void()>>> inbox_;  // guarded by inbox_mutex_
  SceneLoadFunction load_scene_;  // GUI thread; copied into each job
  std::shared_ptr<std::atomic<bool>> cancel_flag_;
  std::uint64_t job_ = 0;  // GUI thread: id of the current job (0: none yet)
  bool busy_ = false;
};

}  // namespace vh::ui
