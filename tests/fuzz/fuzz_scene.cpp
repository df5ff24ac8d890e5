// Fuzz target: scene JSON through vh::runtime::parseScene (from the string; relative paths
// resolve against a temporary folder holding t.csv and tool.stl, then the shared datasets as in
// the application; the files only need to exist: parseScene does not read them).
// Expected: a SceneSpec or std::runtime_error. Anything else (a nlohmann::json exception that
// escaped, std::invalid_argument, ...) is a finding.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "fuzz_support.h"
#include "vh/runtime/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto base_dir = [] {
    const auto dir = vh::fuzz::freshDir("scene");
    vh::fuzz::writeFile(dir / "t.csv", nullptr, 0);
    vh::fuzz::writeFile(dir / "tool.stl", nullptr, 0);
    return dir;
  }();
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const vh::runtime::SceneSpec spec = vh::runtime::parseScene(text, "fuzz.json", base_dir);
    (void)spec;
  } catch (const std::runtime_error& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
