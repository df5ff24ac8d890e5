#pragma once
/// @file
/// The tool choice: the catalogue of tools (tool_catalog.h, plus the scene's own tool), which
/// one is in use, and rebuilding one at a point spacing on the loader thread before the session
/// takes it. Observes the Session: a new scene's or a new tool's entry becomes the current one.
///
/// Threads: GUI thread only; the point shell is resampled on SceneLoader's worker thread.

#include <memory>
#include <vector>

#include <QObject>
#include <QString>

#include "vh/ui/tool_catalog.h"

namespace vh::runtime {
class Session;
}

namespace vh::ui {

class SceneLoader;
struct RebuiltTool;

class ToolPicker : public QObject {
  Q_OBJECT

 public:
  /// The catalogue of `shared_datasets_dir` (toolCatalog()); `session` and `loader` outlive this.
  ToolPicker(runtime::Session& session, SceneLoader& loader, const std::filesystem::path& shared_datasets_dir,
             QObject* parent = nullptr);
  ~ToolPicker() override;

  /// The tools to choose from; the scene's own tool is appended when the catalogue lacks it.
  const std::vector<ToolChoice>& choices() const noexcept { return tools_; }
  /// The catalogue of another shared datasets folder (File > Data Folder); choicesChanged().
  void setSharedDatasetsDir(const std::filesystem::path& shared_datasets_dir);
  /// Index into choices() of the tool in use, -1 before a scene.
  int currentIndex() const noexcept { return index_; }
  /// Rebuilds tool `choice_index` at `point_spacing_m` [m] (0: automatic) for the felt field and
  /// isovalue, then hands it to the session, which ramps the force to zero before the tool
  /// changes under the hand. buildStarted() now, toolChanged() or the loader's failed() later.
  /// Nothing happens without a scene or for an index out of range; message() while loading.
  void select(int choice_index, double point_spacing_m = 0.0);

 signals:
  /// A rebuild began: `label` is the tool's name.
  void buildStarted(const QString& label, double point_spacing_m);
  /// The rebuild ended (built, failed or cancelled).
  void buildEnded();
  /// The session uses the rebuilt tool.
  void toolChanged();
  /// choices() changed (another datasets folder).
  void choicesChanged();
  /// A short text for the status bar.
  void message(const QString& text, int timeout_ms);

 private:
  void onToolBuilt(std::shared_ptr<RebuiltTool> rebuilt);

  runtime::Session& session_;
  SceneLoader& loader_;
  std::vector<ToolChoice> tools_;
  int index_ = -1;
  int observer_ = 0;
};

}  // namespace vh::ui
