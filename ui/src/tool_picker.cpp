#include "vh/ui/tool_picker.h"

#include "vh/runtime/session.h"
#include "vh/ui/scene_loader.h"

namespace vh::ui {

ToolPicker::ToolPicker(runtime::Session& session, SceneLoader& loader, const std::filesystem::path& shared_datasets_dir,
                       QObject* parent)
    : QObject(parent), session_(session), loader_(loader), tools_(toolCatalog(shared_datasets_dir)) {
  observer_ = session_.addObserver([this](runtime::SessionChange what) {
    if (runtime::has(what, runtime::SessionChange::kTool) || runtime::has(what, runtime::SessionChange::kScene)) {
      index_ = findOrAddSceneTool(tools_, session_.live().tool_spec);
    }
  });
  connect(&loader_, &SceneLoader::toolBuilt, this, &ToolPicker::onToolBuilt);
  connect(&loader_, &SceneLoader::failed, this, &ToolPicker::buildEnded);
  connect(&loader_, &SceneLoader::cancelled, this, &ToolPicker::buildEnded);
}

ToolPicker::~ToolPicker() { session_.removeObserver(observer_); }

void ToolPicker::setSharedDatasetsDir(const std::filesystem::path& shared_datasets_dir) {
  tools_ = toolCatalog(shared_datasets_dir);
  index_ = session_.hasScene() ? findOrAddSceneTool(tools_, session_.live().tool_spec) : -1;
  emit choicesChanged();
}

void ToolPicker::select(int choice_index, double point_spacing_m) {
  if (!session_.hasScene() || session_.loaded().volume.field == nullptr || choice_index < 0 ||
      choice_index >= static_cast<int>(tools_.size())) {
    return;
  }
  if (loader_.busy()) {
    emit message("Busy loading; change the tool when it is done", 4000);
    emit buildEnded();
    return;
  }
  const ToolChoice& choice = tools_[static_cast<std::size_t>(choice_index)];
  emit buildStarted(QString::fromStdString(choice.label), point_spacing_m);
  loader_.buildTool(choice_index, choice, point_spacing_m, session_.live().hapticField(),
                    session_.live().hapticIsovalue());
}

void ToolPicker::onToolBuilt(std::shared_ptr<RebuiltTool> rebuilt) {
  emit buildEnded();
  if (!session_.hasScene()) return;
  const ToolChoice& choice = tools_[static_cast<std::size_t>(rebuilt->choice_index)];
  runtime::ToolSpec spec = session_.live().tool_spec;
  spec.mesh = choice.mesh;
  spec.scale_to_m = choice.scale_to_m;
  spec.point_spacing_m = rebuilt->built.point_spacing_m;
  spec.point_count = 0;
  spec.X_WT_initial.R_AB = choice.R_WT;
  spec.initial_orientation_set = true;
  session_.setTool(rebuilt->built.tool, spec, rebuilt->built.X_WT_initial);
  emit toolChanged();
}

}  // namespace vh::ui
