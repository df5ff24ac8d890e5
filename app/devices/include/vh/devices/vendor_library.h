#pragma once
/// @file
/// Vendor SDK libraries loaded at run time (dlopen), never linked: a machine without the SDK
/// builds and runs, and lists the back-end as "not installed". Used by the Force Dimension
/// (dhd_device.h) and OpenHaptics (openhaptics_device.h) back-ends.
///
/// A library is looked up by a list of candidates (file names for the dynamic loader's search
/// path, or absolute paths); an environment variable naming one file (e.g. VH_DHD_LIBRARY)
/// replaces the list, and tests pass the path of a fake library instead.

#include <exception>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace vh::devices {

/// A shared library opened with dlopen(RTLD_NOW | RTLD_LOCAL). The handle is never closed
/// (vendor SDKs start threads of their own that may outlive a dlclose); the library stays
/// mapped until the process ends. Thread-safe after construction.
class VendorLibrary {
 public:
  /// Opens the first candidate that loads.
  /// @throws std::runtime_error listing every candidate tried and the loader's reason
  ///         ("not installed: libdhd.so: cannot open shared object file ...").
  static std::shared_ptr<VendorLibrary> open(const std::vector<std::string>& candidates);

  /// The candidate that loaded (as given).
  const std::string& path() const noexcept { return path_; }
  /// The address of `name`, or null when the library does not export it.
  void* symbol(const char* name) const noexcept;

  /// Sets `fn` to the function `name`. @throws std::runtime_error "LIBRARY lacks NAME" when
  /// missing (an SDK too old or not the vendor's library).
  template <typename Fn>
  void bind(Fn*& fn, const char* name) const {
    fn = reinterpret_cast<Fn*>(symbol(name));
    if (fn == nullptr) missing(name);
  }
  /// Sets `fn` to the function `name`, or null when missing (optional API).
  template <typename Fn>
  void bindOptional(Fn*& fn, const char* name) const noexcept {
    fn = reinterpret_cast<Fn*>(symbol(name));
  }

 private:
  VendorLibrary(void* handle, std::string path) : handle_(handle), path_(std::move(path)) {}
  [[noreturn]] void missing(const char* name) const;

  void* handle_;
  std::string path_;
};

/// The candidates to try: the value of environment variable `env_var` alone when it is set and
/// not empty, else `defaults`.
std::vector<std::string> vendorLibraryCandidates(const char* env_var, const std::vector<std::string>& defaults);

/// Whether a vendor back-end can be used on this machine (for the device picker and logs).
struct VendorStatus {
  std::string kind;       ///< Scene / catalog device kind: "forcedimension" | "openhaptics".
  std::string title;      ///< e.g. "Force Dimension (DHD)".
  bool installed = false; ///< The library loaded and exports every symbol the driver needs.
  std::string library;    ///< The file loaded (empty when not installed).
  std::string detail;     ///< SDK version when installed; why not otherwise.
  /// One line, e.g. "Force Dimension (DHD): not installed (libdhd.so: cannot open ...)".
  std::string label() const;
};

/// A failed load's message as VendorStatus::detail: without its leading "not installed" and
/// the parentheses around the reason ("not installed (libdhd.so: cannot open ...)" ->
/// "libdhd.so: cannot open ...").
std::string notInstalledReason(const std::string& what);

/// Loads a vendor back-end and reports whether it can be used: `load()` returns the loaded API
/// (a std::shared_ptr<const Api> whose `library` is the VendorLibrary it came from) or throws;
/// `describe(api)` gives VendorStatus::detail when installed (e.g. the SDK version). `api` holds
/// the loaded API, or is reset. Never throws: any error is a not-installed status whose detail is
/// notInstalledReason() of the message.
template <class Api, class Load, class Describe>
VendorStatus probeVendor(std::string kind, std::string title, std::shared_ptr<const Api>& api, Load&& load,
                         Describe&& describe) noexcept {
  VendorStatus status;
  status.kind = std::move(kind);
  status.title = std::move(title);
  api.reset();
  try {
    api = load();
    status.installed = true;
    status.library = api->library->path();
    status.detail = describe(*api);
  } catch (const std::exception& e) {
    status.detail = notInstalledReason(e.what());
  } catch (...) {
    status.detail = "unknown error";
  }
  return status;
}

}  // namespace vh::devices
