// A fake Force Dimension DHD library for the driver's tests (never installed). It exports the C
// symbols DhdDevice binds, with the same prototypes (dhdc.h: trailing `char ID`, int results
// -1 on error, metres / N / N*m), plays back a scripted pose sequence (one pose per position
// read, the last one held) and records every force / torque command. Test-only controls are
// the fakedhd_* functions. Written from the public API description; no vendor code.
#include <array>
#include <cstring>
#include <mutex>
#include <string>
#include <vector>

namespace {

struct State {
  std::mutex mutex;
  int device_count = 1;
  int system_type = 104;
  std::string name = "sigma.7";
  bool wrist = true;
  bool active_wrist = true;
  bool calibrated = true;
  double max_force = -1.0;
  double max_torque = -1.0;
  std::vector<std::array<double, 12>> poses;  // p[3] then R row-major
  std::size_t cursor = 0;
  long reads = 0;
  long fail_after_reads = -1;
  std::vector<std::array<double, 6>> commands;
  bool open = false;
  bool force_enabled = false;
  unsigned buttons = 0;
};

State& state() {
  static State s;
  return s;
}

thread_local int t_last_error = 0;

constexpr int kErrorCom = 2;
constexpr int kErrorNoDeviceFound = 5;

int failWith(int error) {
  t_last_error = error;
  return -1;
}

const char* errorText(int error) {
  switch (error) {
    case 0: return "no error";
    case kErrorCom: return "communication error between the host and the haptic device";
    case kErrorNoDeviceFound: return "no compatible Force Dimension device found";
    default: return "undocumented error";
  }
}

/// The current pose; advances the cursor. @return false when the scripted failure is due.
bool nextPose(std::array<double, 12>& pose) {
  State& s = state();
  const std::lock_guard<std::mutex> lock(s.mutex);
  if (s.fail_after_reads >= 0 && s.reads >= s.fail_after_reads) return false;
  ++s.reads;
  if (s.poses.empty()) {
    pose = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    return true;
  }
  pose = s.poses[s.cursor];
  if (s.cursor + 1 < s.poses.size()) ++s.cursor;
  return true;
}

}  // namespace

extern "C" {

// ---- The DHD API subset ------------------------------------------------------------------------

__attribute__((visibility("default"))) int dhdGetDeviceCount() {
  const std::lock_guard<std::mutex> lock(state().mutex);
  return state().device_count;
}
__attribute__((visibility("default"))) int dhdOpenID(char index) {
  State& s = state();
  const std::lock_guard<std::mutex> lock(s.mutex);
  if (index < 0 || index >= s.device_count) return failWith(kErrorNoDeviceFound);
  s.open = true;
  return index;
}
__attribute__((visibility("default"))) int dhdClose(char) {
  const std::lock_guard<std::mutex> lock(state().mutex);
  state().open = false;
  return 0;
}
__attribute__((visibility("default"))) int dhdGetSystemType(char) {
  const std::lock_guard<std::mutex> lock(state().mutex);
  return state().system_type;
}
__attribute__((visibility("default"))) const char* dhdGetSystemName(char) {
  const std::lock_guard<std::mutex> lock(state().mutex);
  return state().name.c_str();
}
__attribute__((visibility("default"))) bool dhdHasWrist(char) { return state().wrist; }
__attribute__((visibility("default"))) bool dhdHasActiveWrist(char) { return state().active_wrist; }
__attribute__((visibility("default"))) int dhdEnableForce(unsigned char on, char) {
  const std::lock_guard<std::mutex> lock(state().mutex);
  state().force_enabled = on != 0;
  return 0;
}
__attribute__((visibility("default"))) int dhdGetPosition(double* px, double* py, double* pz, char) {
  std::array<double, 12> pose;
  if (!nextPose(pose)) return failWith(kErrorCom);
  *px = pose[0];
  *py = pose[1];
  *pz = pose[2];
  return 0;
}
__attribute__((visibility("default"))) int dhdGetPositionAndOrientationFrame(double* px, double* py, double* pz,
                                                                            double matrix[3][3], char) {
  std::array<double, 12> pose;
  if (!nextPose(pose)) return failWith(kErrorCom);
  *px = pose[0];
  *py = pose[1];
  *pz = pose[2];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) matrix[i][j] = pose[3 + 3 * i + j];
  return 0;
}
__attribute__((visibility("default"))) unsigned int dhdGetButtonMask(char) { return state().buttons; }
__attribute__((visibility("default"))) int dhdSetForceAndTorque(double fx, double fy, double fz, double tx, double ty,
                                                               double tz, char) {
  State& s = state();
  const std::lock_guard<std::mutex> lock(s.mutex);
  if (!s.open) return failWith(kErrorCom);
  if (s.commands.size() < 1000000) s.commands.push_back({fx, fy, fz, tx, ty, tz});
  return 0;
}
__attribute__((visibility("default"))) double dhdGetMaxForce(char) { return state().max_force; }
__attribute__((visibility("default"))) double dhdGetMaxTorque(char) { return state().max_torque; }
__attribute__((visibility("default"))) int dhdErrorGetLast() { return t_last_error; }
__attribute__((visibility("default"))) const char* dhdErrorGetLastStr() { return errorText(t_last_error); }
__attribute__((visibility("default"))) void dhdGetSDKVersion(int* major, int* minor, int* release, int* revision) {
  *major = 3;
  *minor = 14;
  *release = 0;
  *revision = 0;
}
// From libdrd (which also carries the DHD API).
__attribute__((visibility("default"))) bool drdIsInitialized(char) { return state().calibrated; }

// ---- Test-only controls --------------------------------------------------------------------------

__attribute__((visibility("default"))) void fakedhd_reset(int device_count, int system_type, const char* name,
                                                         int wrist, int active_wrist, int calibrated,
                                                         double max_force, double max_torque) {
  State& s = state();
  const std::lock_guard<std::mutex> lock(s.mutex);
  s.device_count = device_count;
  s.system_type = system_type;
  s.name = name;
  s.wrist = wrist != 0;
  s.active_wrist = active_wrist != 0;
  s.calibrated = calibrated != 0;
  s.max_force = max_force;
  s.max_torque = max_torque;
  s.poses.clear();
  s.cursor = 0;
  s.reads = 0;
  s.fail_after_reads = -1;
  s.commands.clear();
  s.open = false;
  s.force_enabled = false;
  s.buttons = 0;
}
/// `n` poses of 12 doubles: position [m], then the rotation matrix row by row.
__attribute__((visibility("default"))) void fakedhd_set_poses(const double* poses, int n) {
  State& s = state();
  const std::lock_guard<std::mutex> lock(s.mutex);
  s.poses.resize(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) std::memcpy(s.poses[static_cast<std::size_t>(k)].data(), poses + 12 * k, sizeof(double) * 12);
  s.cursor = 0;
}
/// Position reads fail (DHD_ERROR_COM) once `reads` reads succeeded (< 0: never).
__attribute__((visibility("default"))) void fakedhd_fail_after(long reads) {
  const std::lock_guard<std::mutex> lock(state().mutex);
  state().fail_after_reads = reads;
}
__attribute__((visibility("default"))) long fakedhd_reads() {
  const std::lock_guard<std::mutex> lock(state().mutex);
  return state().reads;
}
__attribute__((visibility("default"))) int fakedhd_command_count() {
  const std::lock_guard<std::mutex> lock(state().mutex);
  return static_cast<int>(state().commands.size());
}
/// Command `i` (force [N], torque [N*m]); @return 0, or -1 when there is none.
__attribute__((visibility("default"))) int fakedhd_command(int i, double out[6]) {
  State& s = state();
  const std::lock_guard<std::mutex> lock(s.mutex);
  if (i < 0 || i >= static_cast<int>(s.commands.size())) return -1;
  std::memcpy(out, s.commands[static_cast<std::size_t>(i)].data(), sizeof(double) * 6);
  return 0;
}
__attribute__((visibility("default"))) int fakedhd_force_enabled() {
  const std::lock_guard<std::mutex> lock(state().mutex);
  return state().force_enabled ? 1 : 0;
}
__attribute__((visibility("default"))) int fakedhd_is_open() {
  const std::lock_guard<std::mutex> lock(state().mutex);
  return state().open ? 1 : 0;
}

}  // extern "C"
