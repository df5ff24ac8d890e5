#include "io_test_support.h"

#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <system_error>

#include <unistd.h>

#include "vh/io/volume_loader.h"

namespace vh::io::test {

fs::path sharedDir() { return fs::path(VH_SHARED_DATASETS_DIR); }
fs::path generatedDir() { return fs::path(VH_GENERATED_DATA_DIR); }

TempDir::TempDir(const std::string& name) {
  path_ = fs::temp_directory_path() /
          ("vh_io_tests_" + std::to_string(::getpid()) + "_" + name);
  std::error_code ec;
  fs::remove_all(path_, ec);
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::string loadErrorOf(const std::function<void()>& f) {
  std::string message;
  bool thrown = false;
  testing::internal::CaptureStderr();
  try {
    f();
  } catch (const vh::io::LoadError& e) {
    message = e.what();
    thrown = true;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected vh::io::LoadError, got another exception: " << e.what();
  }
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err, "") << "VTK text reached stderr instead of the LoadError";
  if (!thrown && message.empty()) ADD_FAILURE() << "expected vh::io::LoadError, none was thrown";
  if (thrown) std::cout << "[LoadError] " << message << "\n";
  return message;
}

void writeFile(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path unpackedBunny(std::string* why_not) {
  const fs::path tarball = sharedDir() / "classic/ct-bunny.tar.zst";
  const fs::path target = generatedDir() / "ct-bunny";
  const fs::path header = target / "bunny.nhdr";
  if (fs::exists(header) && fs::exists(target / "361.raw")) return header;
  if (!fs::exists(tarball)) {
    if (why_not) *why_not = "shared dataset missing: " + tarball.string();
    return {};
  }
  // Unpack into a private folder, then move into place, so that concurrent tests never see a
  // half-written folder.
  const fs::path staging = generatedDir() / ("ct-bunny.unpacking." + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(staging, ec);
  fs::create_directories(staging);
  const std::string cmd = "tar --zstd -xf '" + tarball.string() + "' -C '" + staging.string() +
                          "' 2>/dev/null || (cd '" + staging.string() + "' && cmake -E tar xf '" +
                          tarball.string() + "')";
  if (std::system(cmd.c_str()) != 0 || !fs::exists(staging / "ct-bunny/bunny.nhdr")) {
    fs::remove_all(staging, ec);
    if (why_not) *why_not = "could not unpack " + tarball.string();
    return {};
  }
  fs::rename(staging / "ct-bunny", target, ec);  // fails harmlessly if another test won
  fs::remove_all(staging, ec);
  if (!fs::exists(header)) {
    if (why_not) *why_not = "could not unpack " + tarball.string();
    return {};
  }
  return header;
}

}  // namespace vh::io::test
