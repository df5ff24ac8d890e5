#pragma once
/// @file
/// `volume-haptics run --audio OUT.wav`: the burr's sound of a headless drilling run (vh::audio's
/// model: its pitch falls with the push and the hardness of what it cuts, its level rises with
/// the removal rate, and the alert beeps while a critical segment is touched or cut), rendered
/// tick by tick into a WAV file (48 kHz, mono, 16-bit) that lasts as long as the run.

#include <filesystem>
#include <memory>
#include <string>

#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"

namespace vh::audio {
class TickSoundWriter;
}

namespace vh::app {

/// A run's sound, written as the run ticks.
class RunAudio {
 public:
  /// Refuses a scene the burr never spins in, before anything is loaded: no "drill" section, or
  /// one that is off ("on": false; a headless run never starts the burr).
  /// @throws std::runtime_error saying "--audio needs a drilling scene" and why.
  static void checkScene(const vh::runtime::SceneSpec& spec, const std::string& scene_path);

  /// Creates `wav` for the loaded drilling `scene` (its burr's radius and speed) at the run's
  /// servo rate [Hz]. @throws std::runtime_error naming the file when it cannot be created.
  RunAudio(const std::filesystem::path& wav, const vh::runtime::LoadedScene& scene, double servo_rate_Hz);
  ~RunAudio();

  /// Feeds the run's ticks to the sound (RunOptions::on_drill_tick). This object must outlive the run.
  void attach(vh::runtime::RunOptions& options);
  /// Closes the file. @return a line for the summary: where, how long, at what rate.
  /// @throws std::runtime_error naming the file when the last write fails.
  std::string finish();

 private:
  std::filesystem::path path_;
  std::unique_ptr<vh::audio::TickSoundWriter> writer_;
};

}  // namespace vh::app
