#pragma once
/// @file
/// SHA-256 (FIPS 180-4) for dataset checksums in session recordings (session_metadata.h).
/// Own code: no dependency of the project provides SHA-256 (VTK's vtksys has only MD5, OpenSSL
/// is not a dependency, Qt is not allowed in vh::runtime). Also checks datasets/manifest.json (tests/app/io/manifest_test.cpp).

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace vh::runtime {

class Sha256 {
 public:
  Sha256();
  void update(const void* data, std::size_t size);
  void update(std::string_view s) { update(s.data(), s.size()); }
  /// Lower-case hex digest; the object must not be updated afterwards.
  std::string hexDigest();

 private:
  void block(const std::uint8_t* p);
  std::array<std::uint32_t, 8> h_;
  std::array<std::uint8_t, 64> buffer_{};
  std::size_t buffered_ = 0;
  std::uint64_t length_ = 0;
};

/// Hex SHA-256 of a file's bytes (as `sha256sum` prints).
std::string sha256File(const std::filesystem::path& file);
/// Hex SHA-256 of a folder: of the text "<sha256>  <relative/path>\n" per regular file,
/// sorted by relative path (byte order, '/' separators), i.e. of
/// `find . -type f | sed 's|^\./||' | LC_ALL=C sort | xargs sha256sum`.
std::string sha256Folder(const std::filesystem::path& folder);

}  // namespace vh::runtime
