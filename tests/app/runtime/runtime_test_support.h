#pragma once
// Helpers shared by the runtime tests: scratch folders, files, expected error messages, data paths.
#include <chrono>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <string>

#include <gtest/gtest.h>

#include "vh/runtime/scene.h"

namespace vh::test {

/// A fresh, empty folder under the test output folder, named after the running test.
std::filesystem::path scratchDir();

/// Writes `text` to `path` (creating folders); returns the path.
std::filesystem::path writeText(const std::filesystem::path& path, const std::string& text);

/// The shared real datasets folder (VH_SHARED_DATASETS_DIR).
std::filesystem::path sharedDatasets();
/// The build's generated data folder (VH_GENERATED_DATA_DIR).
std::filesystem::path generatedData();
/// The source tree (VH_SOURCE_DIR).
std::filesystem::path sourceDir();

/// The built-in sphere (radius 20 mm, F = signed distance in mm, isovalue 0) with the 5 mm ball
/// tool (1.5 mm point spacing), coupling 1000 N/m, simulated device; loaded once.
const runtime::LoadedScene& sphereBallScene();

/// Polls `condition` every 2 ms until it holds or `timeout` passes; @return condition().
/// The default is generous (30 s): a condition that holds returns at once on a fast machine,
/// and a loaded one (the servo threads starved for seconds under ctest -j) still gets there.
bool waitUntil(const std::function<bool()>& condition,
               std::chrono::milliseconds timeout = std::chrono::milliseconds(30000));

/// The process's locked memory [kB], as the kernel counts it (VmLck of /proc/self/status); -1
/// when it cannot be read.
long lockedMemory_kB();

/// The bytes of a recording of the current format rewritten as format version 3: the header's
/// version and record size, each record cut after its flags (200 bytes) and each record chunk's
/// CRC-32 recomputed; event chunks and the end marker as they are.
std::string asVersion3Recording(const std::string& current);
/// The same as format version 4: 216-byte records (up to critical_segment, then 4 bytes of 0).
std::string asVersion4Recording(const std::string& current);

}  // namespace vh::test

/// Expects `statement` to throw `exception_type` whose what() contains every one of the given
/// substrings.
#define VH_EXPECT_THROW_WITH(statement, exception_type, ...)                                   \
  do {                                                                                         \
    bool vh_thrown_ = false;                                                                   \
    try {                                                                                      \
      statement;                                                                               \
    } catch (const exception_type& vh_e_) {                                                    \
      vh_thrown_ = true;                                                                       \
      const std::string vh_what_ = vh_e_.what();                                               \
      for (const std::string& vh_part_ : std::initializer_list<std::string>{__VA_ARGS__}) {    \
        EXPECT_NE(vh_what_.find(vh_part_), std::string::npos)                                  \
            << "message \"" << vh_what_ << "\" lacks \"" << vh_part_ << "\"";                  \
      }                                                                                        \
    }                                                                                          \
    EXPECT_TRUE(vh_thrown_) << #statement " did not throw " #exception_type;                   \
  } while (false)
