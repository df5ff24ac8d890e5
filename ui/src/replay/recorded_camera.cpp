// The view's camera in a recording (vh/ui/replay/recorded_camera.h).
#include "vh/ui/replay/recorded_camera.h"

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

namespace vh::ui {
namespace {

nlohmann::json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// A finite 3-vector member, or false.
bool vec3At(const nlohmann::json& j, const char* key, Eigen::Vector3d& out) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_array() || it->size() != 3) return false;
  for (int k = 0; k < 3; ++k) {
    if (!(*it)[static_cast<std::size_t>(k)].is_number()) return false;
    out[k] = (*it)[static_cast<std::size_t>(k)].get<double>();
  }
  return out.allFinite();
}

}  // namespace

std::string cameraEventJson(const ViewCamera& camera) {
  return nlohmann::json{{"position_W_m", vec(camera.position_W_m)},
                        {"focal_W_m", vec(camera.focal_point_W_m)},
                        {"view_up_W", vec(camera.view_up_W)},
                        {"view_angle_deg", camera.view_angle_deg},
                        {"parallel", camera.parallel},
                        {"parallel_scale_m", camera.parallel_scale_m}}
      .dump();
}

std::vector<RecordedCamera> recordedCameras(const runtime::Recording& recording) {
  std::vector<RecordedCamera> out;
  for (const runtime::RecordingEvent& e : recording.events) {
    if (e.type != "camera") continue;
    const nlohmann::json d = nlohmann::json::parse(e.detail_json, nullptr, false);
    if (!d.is_object()) continue;
    RecordedCamera c;
    c.time_s = e.time_s;
    ViewCamera& v = c.camera;
    if (!vec3At(d, "position_W_m", v.position_W_m) || !vec3At(d, "focal_W_m", v.focal_point_W_m) ||
        !vec3At(d, "view_up_W", v.view_up_W))
      continue;
    v.view_angle_deg = d.value("view_angle_deg", 30.0);
    v.parallel = d.value("parallel", false);
    v.parallel_scale_m = d.value("parallel_scale_m", 1.0);
    const Eigen::Vector3d forward = v.focal_point_W_m - v.position_W_m;
    if (!(forward.norm() > 0.0) || !(v.view_up_W.cross(forward).norm() > 0.0) || !std::isfinite(v.view_angle_deg) ||
        !(v.view_angle_deg > 0.0 && v.view_angle_deg < 180.0) || !std::isfinite(v.parallel_scale_m) ||
        !(v.parallel_scale_m > 0.0))
      continue;
    out.push_back(c);
  }
  std::stable_sort(out.begin(), out.end(), [](const RecordedCamera& a, const RecordedCamera& b) { return a.time_s < b.time_s; });
  return out;
}

bool sameView(const ViewCamera& a, const ViewCamera& b) noexcept {
  constexpr double kTol = 1e-9;
  return (a.position_W_m - b.position_W_m).norm() <= kTol && (a.focal_point_W_m - b.focal_point_W_m).norm() <= kTol &&
         (a.view_up_W - b.view_up_W).norm() <= kTol && std::abs(a.view_angle_deg - b.view_angle_deg) <= kTol &&
         a.parallel == b.parallel && std::abs(a.parallel_scale_m - b.parallel_scale_m) <= kTol;
}

}  // namespace vh::ui
