// The scene actors' inputs for a loaded scene and a recorded tick's tool frame (scene_frames.h).
#include "vh/ui/view/scene_frames.h"

#include <vtkImageData.h>

namespace vh::ui {

haptics::Pose proxyPoseOf(const runtime::TickRecord& r) {
  haptics::Pose X;
  X.p_AB_m = Eigen::Vector3d(r.p_WP_m[0], r.p_WP_m[1], r.p_WP_m[2]);
  X.R_AB = Eigen::Quaterniond(r.q_WP[0], r.q_WP[1], r.q_WP[2], r.q_WP[3]).normalized();
  return X;
}

haptics::Pose devicePoseOf(const runtime::TickRecord& r) {
  haptics::Pose X;
  X.p_AB_m = Eigen::Vector3d(r.p_WD_m[0], r.p_WD_m[1], r.p_WD_m[2]);
  X.R_AB = Eigen::Quaterniond(r.q_WD[0], r.q_WD[1], r.q_WD[2], r.q_WD[3]).normalized();
  return X;
}

double forceNormOf(const runtime::TickRecord& r) {
  return Eigen::Vector3d(r.force_W_N[0], r.force_W_N[1], r.force_W_N[2]).norm();
}

SceneActorsSpec sceneActorsSpecFor(const runtime::LoadedScene& scene, const runtime::LiveValues& live) {
  SceneActorsSpec spec;
  spec.image = scene.volume.image.get();
  if (scene.volume.field != nullptr) spec.direction_W = scene.volume.field->geometry().direction_W;
  spec.isovalue = live.isovalue;
  if (live.tool != nullptr) {
    spec.tool_mesh_T = live.tool->mesh_T;
    spec.p_TCm_m = live.tool->mass.p_TCm_m;
  }
  spec.show_device = true;
  spec.hounsfield = scene.volume.info.value_unit == "HU";
  spec.isovalue_from_records = !live.feltSegments();
  return spec;
}

ToolFrame toolFrameOf(const runtime::TickRecord& record) {
  ToolFrame frame;
  frame.X_WP = proxyPoseOf(record);
  frame.X_WD = devicePoseOf(record);
  frame.force_W_N = Eigen::Vector3d(record.force_W_N[0], record.force_W_N[1], record.force_W_N[2]);
  frame.isovalue = record.isovalue;
  return frame;
}

void showRecord(SceneActors& actors, const runtime::TickRecord& record,
                const std::vector<Eigen::Vector3d>& tool_vertices_T_m) {
  showToolFrame(actors, toolFrameOf(record), tool_vertices_T_m);
}

}  // namespace vh::ui
