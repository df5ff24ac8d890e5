#pragma once
/// @file
/// What the view shows of a scene and of a recorded tick: the scene actors' inputs for a loaded
/// scene with its live values, and a recording's record as a tool frame. Owned by the view; the
/// live view (ViewController), the Replay dock and the exports (media_export.h) all use these.

#include <vector>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/tick_record.h"
#include "vh/ui/view/scene_actors.h"

namespace vh::ui {

/// The record's proxy pose X_WP / device pose X_WD (W, metres).
haptics::Pose proxyPoseOf(const runtime::TickRecord& record);
haptics::Pose devicePoseOf(const runtime::TickRecord& record);
/// |F| [N] of a record.
double forceNormOf(const runtime::TickRecord& record);

/// The props' inputs for a loaded scene (image, direction; HU when the volume's unit is HU) with
/// the live isovalue and tool mesh (Session::live(); LiveValues::initial() for a scene as
/// loaded); the device tool shown.
SceneActorsSpec sceneActorsSpecFor(const runtime::LoadedScene& scene, const runtime::LiveValues& live);

/// The picture of `record` (scene_actors.h: ToolFrame): its poses, force and isovalue, no
/// contact points (recordings keep the count only).
ToolFrame toolFrameOf(const runtime::TickRecord& record);

/// Shows `record` on `actors` (showToolFrame(toolFrameOf(record))).
void showRecord(SceneActors& actors, const runtime::TickRecord& record,
                const std::vector<Eigen::Vector3d>& tool_vertices_T_m);

}  // namespace vh::ui
