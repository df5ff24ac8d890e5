#include "vh/devices/vendor_library.h"

#include <dlfcn.h>

#include <cstdlib>
#include <stdexcept>

namespace vh::devices {

std::shared_ptr<VendorLibrary> VendorLibrary::open(const std::vector<std::string>& candidates) {
  std::string reasons;
  for (const std::string& candidate : candidates) {
    dlerror();  // clear
    void* handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle != nullptr) return std::shared_ptr<VendorLibrary>(new VendorLibrary(handle, candidate));
    const char* why = dlerror();
    reasons += (reasons.empty() ? "" : "; ") + std::string(why != nullptr ? why : candidate + ": cannot load");
  }
  if (candidates.empty()) reasons = "no library to try";
  throw std::runtime_error("not installed (" + reasons + ")");
}

void* VendorLibrary::symbol(const char* name) const noexcept { return dlsym(handle_, name); }

void VendorLibrary::missing(const char* name) const {
  throw std::runtime_error("not installed: " + path_ + " lacks " + name + " (not the vendor's library, or an SDK too old)");
}

std::vector<std::string> vendorLibraryCandidates(const char* env_var, const std::vector<std::string>& defaults) {
  const char* value = env_var != nullptr ? std::getenv(env_var) : nullptr;
  if (value != nullptr && *value != '\0') return {std::string(value)};
  return defaults;
}

std::string notInstalledReason(const std::string& what) {
  std::string why = what;
  const std::string prefix = "not installed";
  if (why.rfind(prefix, 0) == 0) why = why.substr(prefix.size());
  while (!why.empty() && (why.front() == ' ' || why.front() == ':')) why.erase(0, 1);
  if (why.size() > 1 && why.front() == '(' && why.back() == ')') why = why.substr(1, why.size() - 2);
  return why;
}

std::string VendorStatus::label() const {
  if (installed) return title + ": " + library + (detail.empty() ? std::string() : " (" + detail + ")");
  return title + ": not installed" + (detail.empty() ? std::string() : " (" + detail + ")");
}

}  // namespace vh::devices
