#include "run_audio.h"

#include <sstream>
#include <stdexcept>

#include "vh/audio/tick_sound.h"
#include "vh/runtime/recording_sound.h"

namespace vh::app {

void RunAudio::checkScene(const vh::runtime::SceneSpec& spec, const std::string& scene_path) {
  if (!spec.drill) {
    throw std::runtime_error("--audio needs a drilling scene: " + scene_path +
                             " has no \"drill\" section (the sound is the burr's)");
  }
  if (!spec.drill->on) {
    throw std::runtime_error("--audio needs a drilling scene: the burr of " + scene_path +
                             " is off (\"drill\": {\"on\": false}) and a headless run never starts it");
  }
}

RunAudio::RunAudio(const std::filesystem::path& wav, const vh::runtime::LoadedScene& scene, double servo_rate_Hz)
    : path_(wav) {
  writer_ = std::make_unique<vh::audio::TickSoundWriter>(wav, servo_rate_Hz, vh::runtime::burrSoundModelOf(scene));
}

RunAudio::~RunAudio() = default;

void RunAudio::attach(vh::runtime::RunOptions& options) {
  options.on_drill_tick = [writer = writer_.get()](const vh::runtime::DrillTick& d) {
    writer->tick({d.burr_on, d.force_N, d.specific_energy_J_per_mm3, d.removal_rate_mm3_per_s}, d.critical);
  };
}

std::string RunAudio::finish() {
  writer_->close();
  std::ostringstream line;
  line << "sound written to " << path_.string() << " ("
       << static_cast<double>(writer_->frames()) / writer_->mixer().sampleRate_Hz() << " s at "
       << writer_->mixer().sampleRate_Hz() << " Hz, " << writer_->mixer().limiter().limitedSamples()
       << " samples limited)";
  return line.str();
}

}  // namespace vh::app
