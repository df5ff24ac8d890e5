#include "vh/runtime/sha256.h"

#include <openssl/evp.h>

#include <algorithm>
#include <fstream>
#include <stdexcept>
#include <vector>

namespace vh::runtime {

void Sha256::CtxFree::operator()(evp_md_ctx_st* ctx) const noexcept { EVP_MD_CTX_free(ctx); }

Sha256::Sha256() : ctx_(EVP_MD_CTX_new()) {
  if (!ctx_ || EVP_DigestInit_ex(ctx_.get(), EVP_sha256(), nullptr) != 1) {
    throw std::runtime_error("SHA-256: libcrypto could not start a digest");
  }
}

Sha256::~Sha256() = default;
Sha256::Sha256(Sha256&&) noexcept = default;
Sha256& Sha256::operator=(Sha256&&) noexcept = default;

void Sha256::update(const void* data, std::size_t size) {
  if (!digest_.empty()) throw std::logic_error("SHA-256: update() after hexDigest()");
  if (size == 0) return;
  if (EVP_DigestUpdate(ctx_.get(), data, size) != 1) throw std::runtime_error("SHA-256: libcrypto update failed");
}

std::string Sha256::hexDigest() {
  if (!digest_.empty()) return digest_;
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (EVP_DigestFinal_ex(ctx_.get(), md, &length) != 1 || length != 32) {
    throw std::runtime_error("SHA-256: libcrypto could not finish the digest");
  }
  static constexpr char kHex[] = "0123456789abcdef";
  digest_.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) {
    digest_ += kHex[md[i] >> 4];
    digest_ += kHex[md[i] & 0xf];
  }
  return digest_;
}

std::string sha256File(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return {};
  Sha256 sha;
  std::vector<char> buf(1 << 20);
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    sha.update(buf.data(), static_cast<std::size_t>(in.gcount()));
  }
  return sha.hexDigest();
}

std::string sha256Folder(const std::filesystem::path& folder) {
  namespace fs = std::filesystem;
  std::vector<std::string> relative;
  for (const auto& e : fs::recursive_directory_iterator(folder)) {
    if (e.is_regular_file()) relative.push_back(fs::relative(e.path(), folder).generic_string());
  }
  std::sort(relative.begin(), relative.end());
  Sha256 listing;
  for (const auto& r : relative) listing.update(sha256File(folder / r) + "  " + r + "\n");
  return listing.hexDigest();
}

}  // namespace vh::runtime
