#pragma once
/// @file
/// The view's camera in a recording: the window's recorder (SessionRecorder) writes a "camera"
/// event when the recording starts and whenever the camera has moved since (at most every
/// status period, 250 ms), so that an exported picture or video (`export --png`, `--video`) is
/// seen as the user saw the session, not from the default camera. Frames W (the scene frame),
/// metres.
///
/// Event detail: {"position_W_m": [x, y, z], "focal_W_m": [x, y, z], "view_up_W": [x, y, z],
/// "view_angle_deg": a, "parallel": false, "parallel_scale_m": s}.

#include <cstdint>
#include <string>
#include <vector>

#include "vh/runtime/recording.h"
#include "vh/ui/view/device_manipulation.h"

namespace vh::ui {

/// The "camera" event's detail for `camera` (JSON object text).
std::string cameraEventJson(const ViewCamera& camera);

/// A recording's camera from its time on.
struct RecordedCamera {
  double time_s = 0.0;     ///< The event's time [s].
  ViewCamera camera;       ///< Position, focal point, view up, angle and projection (no viewport).
};

/// The recording's "camera" events in time order; a malformed one (a missing or non-finite
/// field, the focal point at the eye, a zero or parallel view up) is skipped.
std::vector<RecordedCamera> recordedCameras(const runtime::Recording& recording);

/// Whether two cameras show the same view (position, focal point, view up, angle, projection
/// equal to 1e-9 m and 1e-9).
bool sameView(const ViewCamera& a, const ViewCamera& b) noexcept;

}  // namespace vh::ui
