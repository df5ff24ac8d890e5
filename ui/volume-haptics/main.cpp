// volume-haptics: the application.
//
//   volume-haptics [PATH] [--screenshot PNG] [--isovalue V] [--igtl-port N [--igtl-rate HZ] [--igtl-bind A]
//                  [--igtl-allow A,...]] ...   the GUI (vh::ui)
//   volume-haptics run --scene S.json --trajectory T.csv [--report R.json] [--check] [--record R.vhrec] [--verify-step V]
//                      [--audio OUT.wav]
//                      [--igtl-port N [--igtl-rate HZ] [--igtl-bind A] [--igtl-allow A,...] [--igtl-accept-images]]
//   volume-haptics export R.vhrec [--csv C] [--json J] [--events-csv E] [--hdf5 H.h5 [--hdf5-volume]]
//                         [--video V.ogv [--no-audio]] [--png P --at-s T]
//   volume-haptics report R.vhrec --html OUT.html [--reference E.vhrec] | report DIR --table OUT.csv
//   volume-haptics make-trajectory --scene S.json --out T.csv [...]
//   volume-haptics bench table1|accuracy|stability|drilling|bigscan|render|memory [--short] [--out DIR]   benchmarks
//                      (vh::bench; render, memory: vh::ui_bench)
//   volume-haptics pacs echo|find|get [--host H --port P --aet A] ...   a DICOM server (vh/io/pacs.h)
//
// PATH is a DICOM folder, a NRRD / MetaImage file or a scene .json; without it the built-in
// block-with-hole scene opens. `run` and `make-trajectory` are headless: they never create Qt
// objects (the QApplication is created inside vh::ui::runApplication) and need no display.

#include <cctype>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>

#include "pacs_command.h"
#include "report_command.h"
#include "run_audio.h"
#include "vh_version.h"
#include "vh/io/private_files.h"
#include "vh/bench/bench.h"
#include "vh/devices/device_catalog.h"
#include "vh/igtl/igtl_link.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/anonymize.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/recording_hdf5.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/snapshot_channel.h"
#include "vh/runtime/trajectory.h"
#include "vh/ui/application.h"
#include "vh/ui/bench/memory_bench.h"
#include "vh/ui/bench/render_bench.h"
#include "vh/ui/bench/video_bench.h"
#include "vh/ui/export/media_export.h"

namespace fs = std::filesystem;

namespace {

constexpr int kExitError = 1;
constexpr int kExitCheckFailed = 3;

/// The scene for the GUI's optional positional argument.
vh::runtime::SceneSpec sceneForPath(const std::string& input) {
  if (input.empty()) return vh::runtime::builtinBlockWithHoleScene();
  const fs::path path(input);
  std::error_code ec;
  if (!fs::exists(path, ec)) throw std::runtime_error(input + ": no such file or folder");
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".json") return vh::runtime::loadSceneFile(path);
  return vh::runtime::sceneForVolume(path);
}

Eigen::Vector3d toVector(const std::vector<double>& v, const char* option) {
  if (v.size() != 3) throw std::runtime_error(std::string(option) + ": expected 3 numbers");
  return {v[0], v[1], v[2]};
}

/// --igtl-bind and --igtl-allow, the same for the GUI and `run`.
void addIgtlAccessOptions(CLI::App& app, std::string& bind, std::vector<std::string>& allow) {
  app.add_option("--igtl-bind", bind,
                 "OpenIGTLink: the IPv4 address to listen on; 127.0.0.1 (this machine only) unless named, 0.0.0.0 for "
                 "every interface (then --igtl-allow is required)")
      ->capture_default_str();
  app.add_option("--igtl-allow", allow,
                 "OpenIGTLink: IPv4 addresses of the clients accepted besides 127.0.0.1 (comma-separated or repeated); "
                 "others are refused and logged")
      ->delimiter(',');
}

// ---- GUI (default) ----

/// The GUI's command line (no subcommand).
struct GuiArgs {
  std::string input;
  vh::ui::AppOptions options;
  std::string screenshot;
  std::optional<double> isovalue;
  std::optional<std::string> series;
  std::optional<int> phase;
};

void addGuiOptions(CLI::App& app, GuiArgs& gui) {
  app.add_option("path", gui.input,
                 "DICOM folder, NRRD (.nrrd/.nhdr), MetaImage (.mha/.mhd) or NIfTI (.nii/.nii.gz/.hdr) file, or scene .json "
                 "(default: the built-in block with a hole and a peg)");
  app.add_option("--screenshot", gui.screenshot, "Save a PNG of the window after loading, then quit");
  app.add_option("--screenshot-delay-ms", gui.options.screenshot_delay_ms,
                 "Time from showing the window to the screenshot [ms]")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--isovalue", gui.isovalue, "Initial isovalue in the data's units (HU for CT)");
  app.add_option("--series", gui.series,
                 "DICOM folder: the series to open (number, Series Instance UID or text of its description), as `run "
                 "--series`; default: the series chooser");
  app.add_option("--phase", gui.phase, "4-D DICOM series: the time point (phase, echo) to open, 0-based, as `run --phase`")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--touch", gui.options.touch,
               "After load, bring the simulated device from outside the volume, along the view through its centre, "
               "until the tool rests on the surface");
  app.add_option("--touch-depth-m", gui.options.touch_depth_m, "How far past the surface --touch goes [m]")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--igtl-port", gui.options.igtl_port,
                 "Listen for an OpenIGTLink client (3D Slicer) on this port (18944 is Slicer's default); off without it")
      ->check(CLI::Range(1, 65535));
  app.add_option("--igtl-rate", gui.options.igtl_rate_Hz, "OpenIGTLink frames per second [Hz] (clamped to the servo rate)")
      ->check(CLI::Range(1.0, 100000.0));
  addIgtlAccessOptions(app, gui.options.igtl_bind, gui.options.igtl_allow);
  app.add_option("--servo-log", gui.options.servo_log,
                 "Append a JSON line each second: the haptic threads' rate, longest tick, jitter and deadline misses, "
                 "the view's frames and the CPU time the hypervisor stole in that second (a servo-timing soak)");
  app.add_option("--width", gui.options.window_width, "Window width [logical pixels]")->check(CLI::PositiveNumber);
  app.add_option("--height", gui.options.window_height, "Window height [logical pixels]")->check(CLI::PositiveNumber);
}

// ---- run ----

/// `run`'s command line.
struct RunArgs {
  std::string scene, trajectory, report;
  std::optional<double> isovalue;
  bool check = false;
  std::optional<std::string> series;
  std::optional<int> phase;
  std::string segmentation;
  std::vector<std::string> felt, critical;
  std::string trace;
  std::optional<int> igtl_port;
  double igtl_rate_Hz = 60.0;
  std::string igtl_bind = vh::igtl::LinkOptions{}.bind_address;
  std::vector<std::string> igtl_allow;
  bool igtl_accept_images = false;
  bool anonymize = false;
  std::string record;
  std::string note;
  std::string audio;
  double verify_step = vh::runtime::RunOptions{}.verify_step_voxels;
  bool lag_reference = vh::runtime::RunOptions{}.lag_reference;
  bool fit_check = true;
  std::string guide;
  vh::haptics::GuidanceGains guide_gains;
  vh::runtime::HandImpedance hand;
  CLI::Option* hand_option = nullptr;
};

/// `run`'s guidance options (--guide and the spring's settings, the simulated hand).
void addGuideOptions(CLI::App& run, RunArgs& a) {
  run.add_option("--guide", a.guide,
                 "Haptic guidance: pull the device toward the nearest point of this expert recording's device path "
                 "(.vhrec of the same scan, else refused) with a capped spring faded over repetitions; the "
                 "trajectory becomes the trainee's intended motion and the device yields to the force like a hand "
                 "(--hand-stiffness-N-per-m); --guide-stiffness-N-per-m 0 gives the same run unguided");
  run.add_option("--guide-stiffness-N-per-m", a.guide_gains.stiffness_N_per_m,
                 "Guidance spring stiffness K on the first repetition [N/m] (clamped to the device's rating)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  run.add_option("--guide-cap-N", a.guide_gains.cap_N, "Largest guidance force, never exceeded [N]")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  run.add_option("--guide-deadband-m", a.guide_gains.deadband_m, "No guidance force within this distance of the path [m]")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  run.add_option("--guide-fade", a.guide_gains.fade,
                 "Fade per repetition: the stiffness on repetition r is K x fade^r (guidance withdrawn as the trainee "
                 "repeats the task)")
      ->capture_default_str()
      ->check(CLI::Range(1e-6, 1.0));
  run.add_option("--guide-repetition", a.guide_gains.repetition, "Which repetition this run is (0: the first)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  a.hand_option = run.add_option("--hand-stiffness-N-per-m", a.hand.stiffness_N_per_m,
                                 "The simulated hand's stiffness about the trajectory, its intended motion [N/m] (mass "
                                 "0.5 kg, damping 20 N s/m): the device yields to the force it commands; on with "
                                 "--guide, or when given (e.g. to record an expert the same way)");
  a.hand_option->capture_default_str()->check(CLI::PositiveNumber);
}

CLI::App* addRunSubcommand(CLI::App& app, RunArgs& a) {
  CLI::App* run = app.add_subcommand("run", "Headless: replay a device trajectory through the renderer and "
                                            "report timing, contacts and penetration (no display needed)");
  run->add_option("--scene", a.scene, "Scene .json (its device section is ignored)")->required();
  run->add_option("--trajectory", a.trajectory, "Trajectory CSV: t_s,x_m,y_m,z_m,qw,qx,qy,qz")->required();
  run->add_option("--report", a.report, "Write the JSON report here");
  run->add_flag("--anonymize", a.anonymize,
                "Leave what identifies the patient out of the report: the scene's, the volume's and "
                "the trajectory's paths, the series' description and UID in the volume's notices");
  run->add_option("--isovalue", a.isovalue, "Override the scene's isovalue");
  run->add_option("--series", a.series,
                  "DICOM folder: the series to load (number, Series Instance UID or text of its description); default: the scene's, else the largest");
  run->add_option("--phase", a.phase, "4-D DICOM series: the time point (phase, echo) to load, 0-based")
      ->check(CLI::NonNegativeNumber);
  run->add_option("--segmentation", a.segmentation,
                  "3D Slicer segmentation (.seg.nrrd) or label map on the scan (overrides the scene's)");
  run->add_option("--felt", a.felt,
                  "A segment to feel instead of the scan's isosurface (name or ID; repeat for more)");
  run->add_option("--critical", a.critical, "A segment whose touch is reported as critical (repeatable)");
  run->add_option("--igtl-port", a.igtl_port,
                  "Stream the run over OpenIGTLink on this port (the run then plays in real time)")
      ->check(CLI::Range(1, 65535));
  run->add_option("--igtl-rate", a.igtl_rate_Hz, "OpenIGTLink frames per second [Hz] (clamped to the servo rate)")
      ->check(CLI::Range(1.0, 100000.0));
  addIgtlAccessOptions(*run, a.igtl_bind, a.igtl_allow);
  run->add_flag("--igtl-accept-images", a.igtl_accept_images,
                "OpenIGTLink: receive IMAGE messages (each is logged with its sender; the run keeps its scene); "
                "without it they are refused and logged");
  run->add_option("--trace", a.trace, "Also write one CSV row per tick (poses, force, contacts, time, depth)");
  run->add_option("--record", a.record,
                  "Also write a session recording (.vhrec: metadata, one record per tick, events) here");
  run->add_option("--audio", a.audio,
                  "Also write the burr's sound as a WAV file (48 kHz mono, as long as the run): its pitch falls with "
                  "the push and the hardness of what it cuts, its level rises with the removal rate, and a beep "
                  "sounds while a critical segment is touched or cut; needs a scene whose \"drill\" is on");
  run->add_option("--note", a.note,
                  "Free text kept in the recording's metadata (\"note\"): the cohort table's label (else the file name)");
  run->add_option("--verify-step", a.verify_step,
                  "Crossing check after every tick, outside the timed part: sample each shell point's path with "
                  "this step [voxels]; 0 turns it off")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  run->add_flag("!--no-lag-reference", a.lag_reference,
                "Skip the unbudgeted reference run that measures the work budget's lag");
  run->add_flag("!--no-fit-check", a.fit_check,
                "Skip the fit check before the run: a warm-up of the tool on this scene (a second or less) that says "
                "whether this computer renders it on time (its worst ticks cut at most 0.1 % of the time, the proxy at "
                "most 0.5 mm behind) and, when not, the finest point spacing that fits; the run keeps the tool "
                "either way (the report's tool_fit)");
  run->footer(
      "The summary line: ticks run; exec = the renderer's time per tick (mean, median, 99th percentile, max) [us]; "
      "points of the tool's point shell; contacts (largest set, mean); max force of the coupling [N]; penetration = "
      "deepest shell point inside the isosurface against the tolerance epsilon [mm]; nan ticks; bad samples (not "
      "rendered); crossings = ticks a shell point crossed into the isosurface (must be 0); edges = ticks the tool's "
      "surface between two neighbouring shell points crossed (0 guaranteed with the edge test, the default; not with \"edge_test\": false); "
      "work budget: ticks the per-tick work budget cut; lag = the largest distance [mm] and angle [rad] between "
      "the budgeted proxy and the same run's unbudgeted one, behind = how much farther from the device the budgeted "
      "one was; drilled = volume the burr removed [mm^3]; touched = per segment time, peak force, touches. "
      "More in docs/command-line.md.");
  addGuideOptions(*run, a);
  run->add_flag("--check", a.check,
                "Exit with 3 when the proxy penetrated deeper than epsilon, a tick produced a non-finite value or "
                "the proxy crossed into the isosurface (crossings > 0)");
  return run;
}

/// Creates the folder an output file (`path`, given with `option`) goes into, before anything is
/// loaded, so that a command never fails at its end for want of it.
/// @throws std::runtime_error naming the option, the file and the folder when the folder cannot
///         be created or written in.
void prepareOutputFolder(const std::string& path, const char* option) {
  if (path.empty()) return;
  const std::filesystem::path dir = std::filesystem::absolute(std::filesystem::path(path)).parent_path();
  // Missing folders are created owner-only (0700), as every output of a scan or session is.
  try {
    vh::io::createPrivateDirectories(dir);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string(option) + " " + path + ": " + e.what());
  }
  if (!std::filesystem::is_directory(dir)) {
    throw std::runtime_error(std::string(option) + " " + path + ": cannot create the folder " + dir.string());
  }
  if (::access(dir.c_str(), W_OK) != 0) {
    throw std::runtime_error(std::string(option) + " " + path + ": the folder " + dir.string() + " is not writable");
  }
}

/// The scene file with `run`'s overrides (isovalue, series, phase, segmentation, felt, critical).
vh::runtime::SceneSpec runScene(const RunArgs& a) {
  vh::runtime::SceneSpec spec = vh::runtime::loadSceneFile(a.scene);
  if (a.isovalue) {
    spec.volume.isovalue = *a.isovalue;
    spec.volume.isovalue_set = true;
  }
  if (a.series) spec.volume.series = *a.series;
  if (a.phase) spec.volume.phase = *a.phase;
  if (!a.segmentation.empty()) {
    spec.segmentation = vh::runtime::SegmentationSpec{};
    spec.segmentation->path = std::filesystem::absolute(a.segmentation).string();
  }
  if ((!a.felt.empty() || !a.critical.empty()) && !spec.segmentation) {
    throw std::runtime_error("--felt and --critical need a segmentation (--segmentation or the scene's)");
  }
  if (!a.felt.empty()) spec.segmentation->felt = a.felt;
  if (!a.critical.empty()) spec.segmentation->critical = a.critical;
  return spec;
}

/// OpenIGTLink for `run`: the command line's port, else the scene file's section; the run plays in
/// real time so the client sees the motion at its speed. Null when neither asks for it.
std::unique_ptr<vh::igtl::IgtlLink> startRunLink(const RunArgs& a, vh::runtime::SceneSpec& spec,
                                                 const vh::runtime::SegmentSet* segments,
                                                 vh::runtime::RunOptions& run_options) {
  std::unique_ptr<vh::igtl::IgtlLink> link;
  if (a.igtl_port) spec.openigtlink = vh::runtime::OpenIgtlinkSpec{*a.igtl_port, a.igtl_rate_Hz};
  if (!spec.openigtlink) return link;
  run_options.monitor = std::make_shared<vh::runtime::SnapshotChannel>();
  run_options.realtime = true;
  vh::igtl::LinkOptions link_options;
  link_options.port = spec.openigtlink->port;
  link_options.rate_Hz = spec.openigtlink->rate_Hz;
  link_options.servo_rate_Hz = run_options.servo_rate_Hz;
  link_options.bind_address = a.igtl_bind;
  link_options.allowed_clients = a.igtl_allow;
  link_options.accept_images = a.igtl_accept_images;
  link_options.max_queued_images = 0;  // checked and logged as they come: nothing here opens or declines one
  // Every connection, refusal and rejected message is printed as it happens (wire text escaped).
  link_options.on_notice = [](const std::string& notice) { std::cerr << "volume-haptics run: " << notice << std::endl; };
  if (segments != nullptr) {  // ContactState names the segment touched
    auto names = std::make_shared<vh::runtime::SegmentNameTable>();
    names->set(segments);
    link_options.segment_name = [names](const vh::runtime::HapticSnapshot& snapshot) {
      return names->name(snapshot.contacts > 0 ? snapshot.segment : -1);
    };
  }
  link = std::make_unique<vh::igtl::IgtlLink>(run_options.monitor, link_options);
  link->start();
  std::cout << "volume-haptics run: " << link->statusText() << " at " << link->rate_Hz() << " Hz" << std::endl;
  return link;
}

/// `run`'s report: written and summarised; with --check, the exit code of the check.
int finishRun(const RunArgs& a, const vh::runtime::RunReport& report) {
  if (!a.report.empty()) vh::runtime::writeRunReport(report, a.report);
  std::cout << "volume-haptics run: " << report.summary() << std::endl;
  if (!a.record.empty()) std::cout << "volume-haptics run: recording written to " << a.record << std::endl;
  if (a.check && !report.crossingsChecked())
    std::cerr << "volume-haptics run: warning: --check without the crossing check (--verify-step 0)" << std::endl;
  if (a.check && (report.max_penetration_m > report.epsilon_m || report.nan_ticks > 0 || report.crossings > 0)) {
    std::cerr << "volume-haptics run: check failed: penetration " << report.max_penetration_m * 1e3
              << " mm (epsilon " << report.epsilon_m * 1e3 << " mm), non-finite ticks " << report.nan_ticks
              << ", crossings ";
    if (report.crossingsChecked()) std::cerr << report.crossings;
    else std::cerr << "not checked";
    if (report.crossings > 0)
      std::cerr << " (" << report.crossing_points << (report.crossing_points == 1 ? " point" : " points")
                << ", first at tick " << report.first_crossing_tick << ")";
    std::cerr << std::endl;
    return kExitCheckFailed;
  }
  return EXIT_SUCCESS;
}

int runCommand(const RunArgs& a) {
  prepareOutputFolder(a.report, "--report");
  prepareOutputFolder(a.trace, "--trace");
  prepareOutputFolder(a.record, "--record");
  prepareOutputFolder(a.audio, "--audio");
  vh::runtime::SceneSpec spec = runScene(a);
  if (!a.audio.empty()) vh::app::RunAudio::checkScene(spec, a.scene);
  vh::runtime::RunOptions run_options;
  run_options.on_notice = [](const std::string& notice) {
    std::cerr << "volume-haptics run: warning: " << notice << std::endl;
  };
  run_options.trace_csv = a.trace;
  run_options.record = a.record;
  run_options.record_note = a.note;
  run_options.verify_step_voxels = a.verify_step;
  run_options.lag_reference = a.lag_reference;
  // The scene is loaded once, here: the link names the segments of the scan they were opened on
  // (a DICOM SEG or RT Structure Set is placed on its scan).
  const vh::runtime::Trajectory trajectory = vh::runtime::loadTrajectoryCsv(a.trajectory);
  const vh::runtime::LoadedScene scene = vh::runtime::loadScene(spec);
  for (const std::string& notice : scene.volume.info.notices) run_options.on_notice(notice);
  std::optional<vh::runtime::ToolFit> fit;
  if (a.fit_check) {
    fit = vh::runtime::checkToolFit(vh::runtime::LiveValues::initial(scene));
    if (fit->fits()) {
      std::cout << "volume-haptics run: fit check: " << fit->summary() << std::endl;
    } else {
      run_options.on_notice("the tool does not fit this computer: " + fit->summary() +
                            (fit->suggested ? " (the scene's \"point_spacing_m\" sets it); this run keeps the tool it was given"
                                            : "; this run keeps the tool it was given"));
    }
  }
  std::unique_ptr<vh::app::RunAudio> audio;
  if (!a.audio.empty()) {
    audio = std::make_unique<vh::app::RunAudio>(a.audio, scene, run_options.servo_rate_Hz);
    audio->attach(run_options);
  }
  if (!a.guide.empty()) {
    // The expert's recording must be of this scan (the check `report --reference` makes).
    vh::runtime::SessionInfo info;
    info.device_kind = "scripted";
    run_options.guide = vh::runtime::loadExpertPath(a.guide, vh::runtime::makeSessionMetadata(scene, info));
    run_options.guide_gains = a.guide_gains;
    if (!run_options.guide->damage().empty())
      std::cerr << "volume-haptics run: warning: " << run_options.guide->damage() << std::endl;
  }
  if (!a.guide.empty() || (a.hand_option != nullptr && a.hand_option->count() > 0)) run_options.hand = a.hand;
  std::unique_ptr<vh::igtl::IgtlLink> link = startRunLink(a, spec, scene.segments.get(), run_options);
  vh::runtime::RunReport report = vh::runtime::runHeadless(scene, trajectory, run_options);
  report.trajectory = a.trajectory;
  report.tool_fit = fit;
  if (a.anonymize)
    vh::runtime::anonymizeRunReport(report, {scene.volume.info.description, scene.volume.info.series_uid});
  if (audio) std::cout << "volume-haptics run: " << audio->finish() << std::endl;
  if (link) {
    const vh::igtl::LinkStatus st = link->status();
    link->stop();
    const std::uint64_t volumes = st.images_received;  // logged on arrival; a headless run keeps its scene
    std::cout << "volume-haptics run: OpenIGTLink sent " << st.frames_sent << " frames to " << st.clients
              << (st.clients == 1 ? " client" : " clients") << ", refused " << st.connections_refused
              << " connections and " << st.messages_rejected << " messages, received " << volumes
              << (volumes == 1 ? " volume" : " volumes") << " (not applied)" << std::endl;
  }
  return finishRun(a, report);
}

// ---- make-trajectory ----

/// `make-trajectory`'s command line.
struct MakeTrajectoryArgs {
  std::string scene, out;
  std::optional<double> isovalue;
  vh::runtime::PushSlideOptions push;
  std::vector<double> approach_dir, slide_dir, ray_start;
};

CLI::App* addMakeTrajectorySubcommand(CLI::App& app, MakeTrajectoryArgs& a) {
  CLI::App* make = app.add_subcommand(
      "make-trajectory",
      "Headless: cast the scene's tool down onto the surface and write a push-and-slide trajectory CSV");
  make->add_option("--scene", a.scene, "Scene .json")->required();
  make->add_option("--out", a.out, "Trajectory CSV to write")->required();
  make->add_option("--isovalue", a.isovalue, "Override the scene's isovalue");
  make->add_option("--ray-start", a.ray_start,
                   "Tool origin where the ray starts, x y z in W [m] (default: above the volume's centre)")
      ->expected(3);
  make->add_option("--approach-dir", a.approach_dir, "Push direction x y z in W (default 0 0 -1)")->expected(3);
  make->add_option("--slide-dir", a.slide_dir, "Slide direction x y z in W (default: perpendicular axis)")->expected(3);
  make->add_option("--clearance-m", a.push.start_clearance_m, "Start this far before the first contact [m]");
  make->add_option("--push-depth-m", a.push.push_depth_m, "Push the device this far past the contact [m]");
  make->add_option("--slide-m", a.push.slide_m, "Slide this far tangentially [m]");
  make->add_option("--slide-rotation-rad", a.push.slide_rotation_rad, "Rotate this much while sliding [rad]");
  return make;
}

int makeTrajectoryCommand(MakeTrajectoryArgs& a) {
  prepareOutputFolder(a.out, "--out");
  vh::runtime::SceneSpec spec = vh::runtime::loadSceneFile(a.scene);
  if (a.isovalue) {
    spec.volume.isovalue = *a.isovalue;
    spec.volume.isovalue_set = true;
  }
  const vh::runtime::LoadedScene scene = vh::runtime::loadScene(spec);
  if (!a.approach_dir.empty()) a.push.approach_dir_W = toVector(a.approach_dir, "--approach-dir");
  if (!a.slide_dir.empty()) a.push.slide_dir_W = toVector(a.slide_dir, "--slide-dir");
  // The surface the hand feels (the felt segments' when the scene has some).
  vh::haptics::Pose start = vh::runtime::poseAboveVolume(*scene.hapticField(), scene.tool->point_shell,
                                                         scene.X_WT_initial.R_AB, 0.01);
  if (!a.ray_start.empty()) start.p_AB_m = toVector(a.ray_start, "--ray-start");
  vh::runtime::PushSlidePlan plan;
  try {
    plan = vh::runtime::makePushSlideTrajectory(*scene.hapticField(), scene.tool->point_shell, scene.hapticIsovalue(),
                                                start, a.push);
  } catch (const std::runtime_error& e) {
    // The default ray runs down W's z axis: for a scan in patient coordinates (LPS, +z towards
    // the head) that is along the body, from above the head, where a CT may have no surface.
    const vh::haptics::ScalarVolume& f = *scene.hapticField();
    std::ostringstream hint;
    hint << e.what() << ". The scan spans (" << f.boundsMin_W_m().transpose() << ") to ("
         << f.boundsMax_W_m().transpose() << ") m in W (patient LPS for DICOM: +z towards the head); choose "
         << "--ray-start X Y Z outside the body and --approach-dir towards it (e.g. 0 1 0 from the front, "
         << "1 0 0 from the right), or another --isovalue";
    throw std::runtime_error(hint.str());
  }
  vh::runtime::writeTrajectoryCsv(plan.trajectory, a.out);
  std::cout << "volume-haptics make-trajectory: first contact at (" << plan.X_WD_contact.p_AB_m.transpose()
            << ") m; " << plan.trajectory.size() << " key poses over " << plan.trajectory.duration_s()
            << " s written to " << a.out << std::endl;
  return EXIT_SUCCESS;
}

// ---- export ----

/// `export`'s command line.
struct ExportArgs {
  std::string recording;
  std::string csv;
  std::string json;
  std::string events_csv;
  std::string hdf5;
  bool hdf5_volume = false;
  bool anonymize = false;
  vh::ui::MediaExportOptions media;
};

CLI::App* addExportSubcommand(CLI::App& app, ExportArgs& a) {
  CLI::App* export_cmd = app.add_subcommand("export", "Export a session recording (.vhrec, or one exported as HDF5) "
                                               "as CSV (one row per tick, SI units), JSON metadata and/or one HDF5 file; "
                                               "damage and an unfinished recording are reported");
  export_cmd->add_option("recording", a.recording, "Recording file (.vhrec)")->required();
  export_cmd->add_option("--csv", a.csv, "CSV to write: one row per tick, units in the header");
  export_cmd->add_option("--json", a.json, "JSON to write: the session metadata, a summary and the events");
  export_cmd->add_option("--events-csv", a.events_csv, "CSV to write: one row per event (t_s,tick,type,detail_json)");
  export_cmd->add_option("--hdf5", a.hdf5,
                         "HDF5 file to write: the ticks as one dataset per --csv column (units in attributes), the "
                         "events, markers, metadata and scene (layout: docs/python.md); a regular file, not \"-\"");
  export_cmd->add_flag("--hdf5-volume", a.hdf5_volume,
                       "With --hdf5: also the scan as felt (/volume/scan, with its index -> patient LPS affine) and, "
                       "with a drill, the drilled field at the end (/volume/drilled, from a replay); needs the "
                       "recording's dataset, unchanged");
  export_cmd->add_flag("--anonymize", a.anonymize,
                       "Leave out of --csv, --json and --events-csv what identifies the patient (DICOM PS3.15 "
                       "Annex E, for the fields a recording keeps): paths and file names become ANONYMIZED, the "
                       "series UID a 2.25 UID derived from it, the series description and the start date and time "
                       "are removed; the pictures of --video and --png are not changed");
  export_cmd->add_option("--video", a.media.video,
                         "Ogg/Theora video (.ogv) of the replay, rendered off screen (needs an X display with "
                         "OpenGL, e.g. xvfb-run), with the burr's sound as an Ogg Vorbis track when the burr ran "
                         "(the sound of `run --audio`, heard in a replay of the drilling); prints the frames done "
                         "and the time left, Ctrl+C ends it there (a shorter video that plays)");
  export_cmd->add_option("--png", a.media.png, "PNG of the replay at --at-s");
  export_cmd->add_flag("!--no-overlay", a.media.overlay,
                       "Frames without the overlay (the time, |F| and |torque|, the markers' labels, a critical "
                       "segment drilled)");
  export_cmd->add_flag("!--no-shadow", a.media.shadow,
                       "Frames without the tool's shadow on the surface (the depth cue of the main view)");
  export_cmd->add_flag("!--no-audio", a.media.sound, "A --video without the burr's sound track (Theora only)");
  export_cmd->add_option("--at-s", a.media.png_time_s, "Recording time of the --png frame [s]")
      ->check(CLI::NonNegativeNumber);
  export_cmd->add_option("--fps", a.media.fps, "Video frame rate [frames/s]")->check(CLI::Range(1.0, 120.0));
  export_cmd->add_option("--width", a.media.width, "Frame width [px]")->check(CLI::Range(16, 8192));
  export_cmd->add_option("--height", a.media.height, "Frame height [px]")->check(CLI::Range(16, 8192));
  return export_cmd;
}

/// True when a window can be opened: an X display (VTK renders through GLX), a Wayland one for
/// the Qt window, or a Qt platform chosen on purpose (QT_QPA_PLATFORM, e.g. offscreen).
bool hasDisplay(bool x11_only) {
  const auto set = [](const char* name) {
    const char* v = std::getenv(name);
    return v != nullptr && *v != '\0';
  };
  return set("DISPLAY") || (!x11_only && (set("WAYLAND_DISPLAY") || set("QT_QPA_PLATFORM")));
}

int exportCommand(int argc, char** argv, const ExportArgs& a) {
  // Video frames and pictures are rendered by VTK's X11 render window, which aborts without one.
  if ((!a.media.video.empty() || !a.media.png.empty()) && !hasDisplay(/*x11_only=*/true)) {
    throw std::runtime_error("export --video and --png render with OpenGL and need a display: run it under "
                             "xvfb-run (xvfb-run -a volume-haptics export ...); --csv, --json and --events-csv do not");
  }
  prepareOutputFolder(a.csv, "--csv");
  prepareOutputFolder(a.json, "--json");
  prepareOutputFolder(a.events_csv, "--events-csv");
  prepareOutputFolder(a.hdf5, "--hdf5");
  if (a.hdf5_volume && a.hdf5.empty()) throw std::runtime_error("export --hdf5-volume needs --hdf5 FILE");
  prepareOutputFolder(a.media.video, "--video");
  prepareOutputFolder(a.media.png, "--png");
  vh::runtime::Recording recording = vh::runtime::readRecording(a.recording);
  for (const std::string& w : recording.warnings) std::cerr << "volume-haptics export: warning: " << w << std::endl;
  const std::string recorded_metadata = recording.metadata_json;  // names the dataset --hdf5-volume loads
  if (a.anonymize) vh::runtime::anonymizeRecording(recording, a.recording);
  if (!a.csv.empty()) vh::runtime::writeRecordingCsv(recording, std::filesystem::path(a.csv));
  if (!a.json.empty()) vh::runtime::writeRecordingJson(recording, a.json);
  if (!a.events_csv.empty()) vh::runtime::writeRecordingEventsCsv(recording, std::filesystem::path(a.events_csv));
  if (!a.hdf5.empty() && !a.hdf5_volume) vh::runtime::writeRecordingHdf5(recording, a.hdf5);
  if (!a.hdf5.empty() && a.hdf5_volume) {
    const std::string difference = vh::runtime::writeRecordingHdf5WithVolume(recording, a.hdf5, recorded_metadata);
    if (!difference.empty())
      std::cerr << "volume-haptics export: warning: --hdf5-volume: " << difference
                << "; the drilled field is left out of " << a.hdf5 << std::endl;
  }
  if (!a.media.video.empty() || !a.media.png.empty()) {
    if (vh::ui::exportRecordingMedia(argc, argv, a.recording, a.media) != 0) return kExitError;
  }
  // With an output on the standard output ("-"), the summary goes to the standard error.
  const bool to_stdout = vh::io::namesStandardOutput(a.csv) || vh::io::namesStandardOutput(a.json) ||
                         vh::io::namesStandardOutput(a.events_csv);
  std::ostream& said = to_stdout ? std::cerr : std::cout;
  said << "volume-haptics export: " << recording.records.size() << " records, " << recording.events.size()
            << " events in " << recording.chunks << " chunks, " << recording.dropped_records << " dropped"
            << std::endl;
  return EXIT_SUCCESS;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"VolumeHaptics: feel the isosurfaces of CT/MR volumes with a 6-DOF haptic tool "
               "(Chan et al., WHC 2011)."};
  app.require_subcommand(0, 1);
  app.set_version_flag("--version", std::string("volume-haptics ") + VH_VERSION + " (git " + VH_GIT_REVISION + ")",
                       "The version and the git revision it was built from, then exit");
  // The subcommands in the order --help lists them.
  GuiArgs gui;
  addGuiOptions(app, gui);
  RunArgs run_args;
  CLI::App* run = addRunSubcommand(app, run_args);
  MakeTrajectoryArgs make_args;
  CLI::App* make = addMakeTrajectorySubcommand(app, make_args);
  ExportArgs export_args;
  CLI::App* export_cmd = addExportSubcommand(app, export_args);
  std::function<int()> report_handler;
  vh::app::addReportSubcommand(app, report_handler);
  std::function<int()> bench_handler;
  CLI::App* bench = vh::bench::addBenchSubcommand(app, bench_handler);
  vh::ui::addRenderBenchSubcommand(*bench, bench_handler);  // renders with the window's view
  vh::ui::addMemoryBenchSubcommand(*bench, bench_handler);  // measures the window's process
  vh::ui::addVideoBenchSubcommand(*bench, bench_handler);   // times `export --video`
  std::function<int()> pacs_handler;
  vh::app::addPacsSubcommand(app, pacs_handler);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    // Hardware kinds ("spacemouse", "falcon") for the scene files parsed below.
    vh::devices::registerDeviceKinds();
    if (*run) return runCommand(run_args);
    if (*export_cmd) return exportCommand(argc, argv, export_args);
    if (*make) return makeTrajectoryCommand(make_args);
    if (report_handler) return report_handler();
    if (bench_handler) return bench_handler();
    if (pacs_handler) return pacs_handler();

    // GUI: the path first (a missing file is said as such), then the display.
    vh::runtime::SceneSpec scene = sceneForPath(gui.input);
    if (!hasDisplay(/*x11_only=*/false)) {
      throw std::runtime_error("the window needs a display (none in DISPLAY or WAYLAND_DISPLAY): run it on a "
                               "desktop, or under xvfb-run for a --screenshot; the headless subcommands (run, "
                               "export --csv, make-trajectory, bench, pacs) need none");
    }
    if (gui.series) scene.volume.series = *gui.series;
    if (gui.phase) scene.volume.phase = *gui.phase;
    gui.options.screenshot = gui.screenshot;
    gui.options.isovalue = gui.isovalue;
    return vh::ui::runApplication(argc, argv, scene, gui.options);
  } catch (const std::exception& e) {
    std::cerr << "volume-haptics: error: " << e.what() << std::endl;
    return kExitError;
  }
}
