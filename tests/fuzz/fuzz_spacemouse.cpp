// Fuzz target: SpaceMouse HID input reports through the driver's pure code: each report into
// spacemouse::decodeReport() as the reader thread does, then the state through deflection() and
// RateController::step() as SpaceMouseDevice::read() does (every model's axis map), and the
// vendor / product id lookup.
// Input: a sequence of reports, each one length byte (mod 65; the driver reads at most 64
// bytes) and that many bytes (the report id first); the first 4 bytes are also a VID and PID.
// Expected: no crash, no sanitizer report, a finite pose in the workspace ball.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "vh/devices/spacemouse_protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace sm = vh::devices::spacemouse;
  if (size >= 4) {
    const auto vid = static_cast<std::uint16_t>(data[0] | data[1] << 8);
    const auto pid = static_cast<std::uint16_t>(data[2] | data[3] << 8);
    (void)sm::findModel(vid, pid);
  }
  const sm::RateControlOptions options;
  sm::RateController controller(options);
  sm::State state;
  const auto models = sm::knownModels();
  std::size_t report_index = 0;
  std::size_t at = 0;
  while (at < size) {
    const std::size_t n = data[at] % 65;
    ++at;
    const std::size_t take = n < size - at ? n : size - at;
    (void)sm::decodeReport(data + at, take, state);
    at += take;
    const sm::AxisMap& axes = models.empty() ? sm::kDefaultAxisMap : models[report_index++ % models.size()].axes;
    controller.step(sm::deflection(state, axes, options), 0.001 * static_cast<double>(n));
    const auto& p = controller.pose().p_AB_m;
    if (!p.allFinite() || p.norm() > options.workspace_radius_m * (1.0 + 1e-9)) std::abort();
  }
  return 0;
}
