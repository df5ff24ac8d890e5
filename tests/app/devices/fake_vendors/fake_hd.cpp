// A fake OpenHaptics HD library for the driver's tests (never installed). It exports the C
// symbols OpenHapticsDevice binds, with the same prototypes and enum values (HD/hd.h,
// HD/hdDefines.h of OpenHaptics 3.x), and behaves like the real one on the driver's path: a
// scheduler thread runs scheduled callbacks at about 1 kHz; the current force and torque may be
// set only inside hdBeginFrame / hdEndFrame (else an error is queued); errors queue up and
// hdGetError pops the oldest. It plays back scripted transforms (column-major 4 x 4 in mm, one per
// frame, the last one held) and records the force [N] and torque [mN*m] of every frame.
// Test-only controls are the fakehd_* functions. Written from the public API description.
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#define VH_EXPORT __attribute__((visibility("default")))

namespace {

using HHD = unsigned int;
using HDenum = unsigned int;
using HDerror = unsigned int;
using HDCallbackCode = unsigned int;
using HDSchedulerHandle = unsigned long;
struct HDErrorInfo {
  HDerror errorCode;
  int internalErrorCode;
  HHD hHD;
};
using Callback = HDCallbackCode (*)(void*);

constexpr HHD kInvalidHandle = 0xFFFFFFFFu;
constexpr HDerror kInvalidEnum = 0x0100;
constexpr HDerror kInvalidOperation = 0x0102;
constexpr HDerror kDeviceFault = 0x0300;
constexpr HDerror kCommError = 0x0302;
constexpr HDerror kIllegalBegin = 0x0400;
constexpr HDerror kIllegalEnd = 0x0401;

struct Scheduled {
  HDSchedulerHandle handle;
  Callback callback;
  void* data;
};

struct State {
  std::recursive_mutex mutex;
  // configuration
  bool has_device = true;
  int input_dof = 6;
  int output_dof = 3;
  unsigned calibration = 0x5000;
  int calibration_style = 1 << 1;
  double max_force = 3.3;
  double max_stiffness = 1.26;
  double max_torque_mNm = 0.0;
  std::string model = "Touch";
  std::vector<std::array<double, 16>> transforms;
  long fail_at_frame = -1;
  HDerror fail_code = kCommError;
  // device state
  HHD open = kInvalidHandle;
  bool force_output = false;
  bool in_frame = false;
  long frames = 0;
  std::size_t cursor = 0;
  std::array<double, 6> frame_command{};
  std::vector<std::array<double, 6>> commands;
  std::deque<HDErrorInfo> errors;
  int calibration_updates = 0;
  // scheduler
  bool running = false;
  std::thread thread;
  std::vector<Scheduled> async;
  std::deque<std::pair<Scheduled, bool*>> sync;
  HDSchedulerHandle next_handle = 1;
  std::condition_variable_any done;
};

State& state() {
  static State s;
  return s;
}

void pushError(HDerror code, int internal = 0) {
  State& s = state();
  s.errors.push_back({code, internal, s.open});
}

void schedulerLoop() {
  State& s = state();
  auto next = std::chrono::steady_clock::now();
  for (;;) {
    std::vector<Scheduled> async;
    std::deque<std::pair<Scheduled, bool*>> sync;
    {
      const std::lock_guard<std::recursive_mutex> lock(s.mutex);
      if (!s.running) break;
      async = s.async;
      sync.swap(s.sync);
    }
    for (auto& [item, flag] : sync) {
      while (item.callback(item.data) != 0) {
      }
      const std::lock_guard<std::recursive_mutex> lock(s.mutex);
      *flag = true;
    }
    if (!sync.empty()) s.done.notify_all();
    for (const Scheduled& item : async) {
      if (item.callback(item.data) == 0) {
        const std::lock_guard<std::recursive_mutex> lock(s.mutex);
        std::erase_if(s.async, [&](const Scheduled& a) { return a.handle == item.handle; });
      }
    }
    next += std::chrono::milliseconds(1);
    std::this_thread::sleep_until(next);
  }
}

}  // namespace

extern "C" {

// ---- The HD API subset -------------------------------------------------------------------------

VH_EXPORT HHD hdInitDevice(const char*) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  if (!s.has_device) {
    pushError(kDeviceFault, -1);
    return kInvalidHandle;
  }
  s.open = 1;
  return s.open;
}
VH_EXPORT void hdDisableDevice(HHD) {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  state().open = kInvalidHandle;
  state().force_output = false;
}
VH_EXPORT void hdMakeCurrentDevice(HHD) {}
VH_EXPORT HDErrorInfo hdGetError() {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  if (s.errors.empty()) return {0, 0, s.open};
  const HDErrorInfo e = s.errors.front();
  s.errors.pop_front();
  return e;
}
VH_EXPORT const char* hdGetErrorString(HDerror code) {
  switch (code) {
    case 0: return "No error";
    case kInvalidEnum: return "Invalid enumerant";
    case kInvalidOperation: return "Invalid operation";
    case kDeviceFault: return "Device fault";
    case kCommError: return "Communication error";
    case kIllegalBegin: return "Illegal begin frame";
    case kIllegalEnd: return "Illegal end frame";
    default: return "Unknown error";
  }
}
VH_EXPORT void hdEnable(HDenum cap) {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  if (cap == 0x4000) state().force_output = true;
}
VH_EXPORT void hdDisable(HDenum cap) {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  if (cap == 0x4000) state().force_output = false;
}
VH_EXPORT void hdBeginFrame(HHD) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  if (s.in_frame || !s.running) {
    pushError(kIllegalBegin);
    return;
  }
  s.in_frame = true;
  s.frame_command = {};
}
VH_EXPORT void hdEndFrame(HHD) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  if (!s.in_frame) {
    pushError(kIllegalEnd);
    return;
  }
  s.in_frame = false;
  ++s.frames;
  if (s.fail_at_frame >= 0 && s.frames >= s.fail_at_frame && s.frames == s.fail_at_frame) pushError(s.fail_code, 7);
  if (s.force_output && s.commands.size() < 1000000) s.commands.push_back(s.frame_command);
  if (s.cursor + 1 < s.transforms.size()) ++s.cursor;
}
VH_EXPORT void hdGetDoublev(HDenum what, double* out) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  switch (what) {
    case 0x2052:  // HD_CURRENT_TRANSFORM
      if (s.transforms.empty()) {
        const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        std::memcpy(out, identity, sizeof identity);
      } else {
        std::memcpy(out, s.transforms[s.cursor].data(), sizeof(double) * 16);
      }
      break;
    case 0x2603: *out = s.max_force; break;        // HD_NOMINAL_MAX_FORCE [N]
    case 0x2602: *out = s.max_stiffness; break;    // HD_NOMINAL_MAX_STIFFNESS [N/mm]
    case 0x2609: *out = 0.005; break;              // HD_NOMINAL_MAX_DAMPING [N*s/mm]
    case 0x2622: *out = s.max_torque_mNm; break;   // HD_NOMINAL_MAX_TORQUE_FORCE [mN*m]
    case 0x2620: *out = s.max_torque_mNm > 0 ? 50.0 : 0.0; break;  // [mN*m/rad]
    case 0x2551: {  // HD_USABLE_WORKSPACE_DIMENSIONS [mm]
      const double box[6] = {-80, -60, -35, 80, 60, 35};
      std::memcpy(out, box, sizeof box);
      break;
    }
    default: pushError(kInvalidEnum);
  }
}
VH_EXPORT void hdGetIntegerv(HDenum what, int* out) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  switch (what) {
    case 0x2000: *out = 0; break;                    // HD_CURRENT_BUTTONS
    case 0x2553: *out = s.input_dof; break;          // HD_INPUT_DOF
    case 0x2554: *out = s.output_dof; break;         // HD_OUTPUT_DOF
    case 0x2555: *out = s.calibration_style; break;  // HD_CALIBRATION_STYLE
    default: pushError(kInvalidEnum);
  }
}
VH_EXPORT const char* hdGetString(HDenum what) {
  State& s = state();
  switch (what) {
    case 0x2501: return s.model.c_str();
    case 0x2503: return "3D Systems";
    case 0x2504: return "FAKE-0001";
    default: return "";
  }
}
VH_EXPORT void hdSetDoublev(HDenum what, const double* values) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  if (!s.in_frame) {  // forces only inside a frame
    pushError(kInvalidOperation);
    return;
  }
  if (what == 0x2700) {
    std::memcpy(s.frame_command.data(), values, sizeof(double) * 3);
  } else if (what == 0x2701 && s.output_dof >= 6) {
    std::memcpy(s.frame_command.data() + 3, values, sizeof(double) * 3);
  } else {
    pushError(kInvalidEnum);
  }
}
VH_EXPORT void hdStartScheduler() {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  if (s.running) return;
  s.running = true;
  s.thread = std::thread(schedulerLoop);
}
VH_EXPORT void hdStopScheduler() {
  State& s = state();
  std::thread t;
  {
    const std::lock_guard<std::recursive_mutex> lock(s.mutex);
    s.running = false;
    t.swap(s.thread);
  }
  if (t.joinable()) t.join();
}
VH_EXPORT HDSchedulerHandle hdScheduleAsynchronous(Callback callback, void* data, unsigned short) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  const HDSchedulerHandle h = s.next_handle++;
  s.async.push_back({h, callback, data});
  return h;
}
VH_EXPORT void hdScheduleSynchronous(Callback callback, void* data, unsigned short) {
  State& s = state();
  bool finished = false;
  std::unique_lock<std::recursive_mutex> lock(s.mutex);
  if (!s.running) {
    pushError(kInvalidOperation);
    return;
  }
  s.sync.push_back({{0, callback, data}, &finished});
  s.done.wait(lock, [&] { return finished || !s.running; });
}
VH_EXPORT void hdUnschedule(HDSchedulerHandle handle) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  std::erase_if(s.async, [&](const Scheduled& a) { return a.handle == handle; });
}
VH_EXPORT HDenum hdCheckCalibration() {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  return state().calibration;
}
VH_EXPORT void hdUpdateCalibration(HDenum) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  ++s.calibration_updates;
  if (s.calibration == 0x5001) s.calibration = 0x5000;
}

// ---- Test-only controls --------------------------------------------------------------------------

VH_EXPORT void fakehd_reset(int has_device, int input_dof, int output_dof, unsigned calibration, int calibration_style,
                            double max_force_N, double max_stiffness_N_per_mm, double max_torque_mNm, const char* model) {
  hdStopScheduler();
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  s.has_device = has_device != 0;
  s.input_dof = input_dof;
  s.output_dof = output_dof;
  s.calibration = calibration;
  s.calibration_style = calibration_style;
  s.max_force = max_force_N;
  s.max_stiffness = max_stiffness_N_per_mm;
  s.max_torque_mNm = max_torque_mNm;
  s.model = model;
  s.transforms.clear();
  s.fail_at_frame = -1;
  s.open = kInvalidHandle;
  s.force_output = false;
  s.in_frame = false;
  s.frames = 0;
  s.cursor = 0;
  s.commands.clear();
  s.errors.clear();
  s.calibration_updates = 0;
  s.async.clear();
  s.sync.clear();
}
/// `n` transforms of 16 doubles (column-major 4 x 4, translation in mm), one per frame.
VH_EXPORT void fakehd_set_transforms(const double* m, int n) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  s.transforms.resize(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) std::memcpy(s.transforms[static_cast<std::size_t>(k)].data(), m + 16 * k, sizeof(double) * 16);
  s.cursor = 0;
}
/// Frame number `frame` (counted from 1 since the reset) ends with error `code`.
VH_EXPORT void fakehd_fail_at_frame(long frame, unsigned code) {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  state().fail_at_frame = frame;
  state().fail_code = code;
}
VH_EXPORT long fakehd_frames() {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  return state().frames;
}
VH_EXPORT int fakehd_command_count() {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  return static_cast<int>(state().commands.size());
}
/// Frame command `i`: force [N], torque [mN*m]. @return 0, or -1 when there is none.
VH_EXPORT int fakehd_command(int i, double out[6]) {
  State& s = state();
  const std::lock_guard<std::recursive_mutex> lock(s.mutex);
  if (i < 0 || i >= static_cast<int>(s.commands.size())) return -1;
  std::memcpy(out, s.commands[static_cast<std::size_t>(i)].data(), sizeof(double) * 6);
  return 0;
}
VH_EXPORT int fakehd_force_output() {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  return state().force_output ? 1 : 0;
}
VH_EXPORT int fakehd_scheduler_running() {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  return state().running ? 1 : 0;
}
VH_EXPORT int fakehd_calibration_updates() {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  return state().calibration_updates;
}
VH_EXPORT int fakehd_pending_errors() {
  const std::lock_guard<std::recursive_mutex> lock(state().mutex);
  return static_cast<int>(state().errors.size());
}

}  // extern "C"
