// Fuzz target: trajectory CSV through vh::runtime::parseTrajectoryCsv, then the parsed
// trajectory queried as the scripted device does (poseAt with and without a cursor, before,
// inside and after its time span).
// Expected: a Trajectory or std::runtime_error. Anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>

#include "fuzz_support.h"
#include "vh/runtime/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const vh::runtime::Trajectory t = vh::runtime::parseTrajectoryCsv(in, "fuzz.csv");
    std::size_t cursor = 0;
    const double t0 = t.startTime_s();
    const double d = t.duration_s();
    volatile double sink = 0.0;
    for (int i = -1; i <= 9; ++i) {
      const double time_s = t0 + d * i / 8.0;
      sink = sink + t.poseAt(time_s, cursor).p_AB_m.x() + t.poseAt(time_s).R_AB.w();
    }
  } catch (const std::runtime_error& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
