#pragma once
/// @file
/// Helpers for the vh::io tests: dataset locations, temporary folders, error capture.

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>

#include <gtest/gtest.h>

namespace vh::io::test {

namespace fs = std::filesystem;

/// The shared real datasets folder (VH_SHARED_DATASETS_DIR).
fs::path sharedDir();
/// This build's generated-data folder (VH_GENERATED_DATA_DIR).
fs::path generatedDir();

/// A fresh, empty folder removed again when the object dies.
class TempDir {
 public:
  explicit TempDir(const std::string& name);
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

/// Runs `f`, which must throw vh::io::LoadError; returns its message ("" and a test failure
/// otherwise). Also fails the test when anything reached stderr meanwhile (VTK messages must
/// become the LoadError, not console text).
std::string loadErrorOf(const std::function<void()>& f);

/// Writes `bytes` to `path`.
void writeFile(const fs::path& path, const std::string& bytes);
/// Reads a whole file.
std::string readFile(const fs::path& path);

/// The CT bunny's bunny.nhdr, unpacked once from the shared tarball into the build tree;
/// empty when the tarball is missing or cannot be unpacked.
fs::path unpackedBunny(std::string* why_not);

/// Seconds since `t0`.
inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace vh::io::test

/// Skips the test when a shared dataset is absent; otherwise defines `var` as its path.
#define VH_REQUIRE_SHARED(var, relative)                                              \
  const std::filesystem::path var = ::vh::io::test::sharedDir() / (relative);         \
  if (!std::filesystem::exists(var)) {                                                 \
    GTEST_SKIP() << "shared dataset missing: " << var.string();                        \
  }

/// Expects `part` in `text` (a message).
#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text)
