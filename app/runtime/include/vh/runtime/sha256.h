#pragma once
/// @file
/// SHA-256 (FIPS 180-4) for dataset checksums in session recordings (session_metadata.h), the
/// drilled field's checksum in run reports and datasets/manifest.json's checks
/// (tests/app/io/manifest_test.cpp). The digest is OpenSSL libcrypto's (EVP digest API); this
/// header does not include OpenSSL's.

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

struct evp_md_ctx_st;  // OpenSSL's EVP_MD_CTX

namespace vh::runtime {

/// Incremental SHA-256 of a byte stream: update() any number of times, then hexDigest().
/// Move-only. Not for the servo loop (it allocates).
class Sha256 {
 public:
  /// @throws std::runtime_error when libcrypto cannot start a SHA-256 digest.
  Sha256();
  ~Sha256();
  Sha256(Sha256&&) noexcept;
  Sha256& operator=(Sha256&&) noexcept;
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;

  /// Appends `size` bytes at `data`.
  /// @throws std::logic_error after hexDigest(); std::runtime_error when libcrypto fails.
  void update(const void* data, std::size_t size);
  void update(std::string_view s) { update(s.data(), s.size()); }
  /// Lower-case hex digest (64 characters) of everything updated so far; the object must not be
  /// updated afterwards (a second call returns the same digest).
  /// @throws std::runtime_error when libcrypto fails.
  std::string hexDigest();

 private:
  struct CtxFree {
    void operator()(evp_md_ctx_st* ctx) const noexcept;
  };
  std::unique_ptr<evp_md_ctx_st, CtxFree> ctx_;
  std::string digest_;  ///< empty until hexDigest()
};

/// Hex SHA-256 of a file's bytes (as `sha256sum` prints); empty when the file cannot be opened.
std::string sha256File(const std::filesystem::path& file);
/// Hex SHA-256 of a folder: of the text "<sha256>  <relative/path>\n" per regular file,
/// sorted by relative path (byte order, '/' separators), i.e. of
/// `find . -type f | sed 's|^\./||' | LC_ALL=C sort | xargs sha256sum`.
std::string sha256Folder(const std::filesystem::path& folder);

}  // namespace vh::runtime
