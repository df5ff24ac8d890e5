#pragma once
/// @file
/// The Qt6 desktop application: main window with a VTK render view of the volume's isosurface,
/// the proxy and device tools, contact points, the force vector, and live statistics.
///
/// Mouse controls in the view (also shown on screen):
///   left drag                 camera trackball (rotate)      | middle drag / wheel: pan / zoom
///   Ctrl + left drag          move the simulated device in the view plane
///   Ctrl + wheel              move the simulated device along the view direction
///   Ctrl + right drag (vert.) same, continuous
///   Shift + left drag         rotate the simulated device (trackball about its centre)

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "vh/haptics/pose.h"
#include "vh/ui/view/render_presets.h"

namespace vh::runtime {
struct SceneSpec;
}

namespace vh::ui {

/// Options of one application run (command line of volume-haptics).
struct AppOptions {
  /// Non-empty: after the scene loaded and `screenshot_delay_ms` of haptic ticks and frames
  /// (with `touch`, and once the tool rests on the surface and the view is on it),
  /// save a PNG of the main window (the VTK view composited in) here, then quit with 0
  /// (1 when the file could not be written).
  std::filesystem::path screenshot;
  /// Initial isovalue in the data's units (HU for CT); overrides the scene's.
  std::optional<double> isovalue;
  /// Time from the window being shown to the screenshot [ms].
  int screenshot_delay_ms = 1500;
  /// Scripted pose X_WD of the simulated device (world frame W, metres), set once after load.
  std::optional<haptics::Pose> device_pose;
  /// Scripted "touch" (for screenshots): after load, the simulated device moves from its initial
  /// pose straight towards the volume's centre until the tool's point shell meets the isosurface
  /// (a cast through the field, runtime::firstContactDistance), then `touch_depth_m` further, so
  /// the proxy rests on the surface while the device sinks in and a contact force shows. When that
  /// ray slips through a hole, starts on rings around it (up to 30% of the volume's size) are
  /// tried; the device then moves sideways first and goes in 0.3 s later. The camera then moves
  /// close to the tool (MainWindow::focusOnTool) to show the contact. Ignored when
  /// `device_pose` is set or the scene has no simulated device (a warning on stderr).
  bool touch = false;
  /// How far past the surface the device target goes for `touch` [m].
  double touch_depth_m = 0.003;
  /// Rendering mode and composite preset for this run; unset: the saved preferences'.
  std::optional<RenderMode> render_mode;
  std::optional<VolumePreset> preset;
  /// Main window size in logical pixels (interactive runs restore the saved size instead, when
  /// there is one).
  int window_width = 1280;
  int window_height = 860;
  /// Set: the OpenIGTLink server listens on this port from the start (it overrides a
  /// scene file's "openigtlink" section); unset: off unless the scene or the GUI switches it on.
  std::optional<int> igtl_port;
  /// The OpenIGTLink server's address and the clients allowed besides 127.0.0.1
  /// (igtl::LinkOptions::bind_address, allowed_clients); only the command line and the dialog
  /// set them (a scene file cannot open the link to other machines).
  std::string igtl_bind = "127.0.0.1";
  std::vector<std::string> igtl_allow;
  /// Its frame rate [Hz] (clamped to the servo rate).
  double igtl_rate_Hz = 60.0;
  /// Non-empty: once a second, one JSON line appended here with the haptic threads' timing over
  /// the last second as the status line shows it (each thread's rate [Hz], longest tick [us],
  /// jitter [us], deadline misses in that second), the view's frames in that second and the CPU
  /// time the hypervisor stole from this machine in it [ms] (/proc/stat; a virtual machine's
  /// vCPUs given to others: what no thread priority inside it can win back). What a servo-timing
  /// soak reads (packaging/servo-soak.sh).
  std::filesystem::path servo_log;
};

/// Sets the default surface format VTK's rendering needs (OpenGL 3.2 core, RGBA 8 bits, depth 24,
/// stencil 8, double buffered, no multisampling); call it before the QApplication exists.
void setDefaultSurfaceFormat();

/// Creates the QApplication (default surface format set before: OpenGL 3.2 core, depth 24,
/// stencil 8, samples 0), shows the main window at once and loads `scene` on a worker thread
/// with a progress bar (a DICOM folder with several series asks which one). Errors: a dialog
/// naming the file and the problem (also printed to stderr); the window stays open so another
/// file can be opened (File menu, drag and drop); a scripted screenshot run exits with 1
/// instead. Starts the haptic thread when the scene has a device; closing the window stops it
/// (force ramped to zero) before the VTK objects are destroyed, and saves the settings.
/// @return the event loop's exit code (0 on a normal close or a successful screenshot).
int runApplication(int argc, char** argv, const vh::runtime::SceneSpec& scene,
                   const AppOptions& options);

}  // namespace vh::ui
