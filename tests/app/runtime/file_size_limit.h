#pragma once
/// @file
/// A full disk, as writers see it, for tests: while a FileSizeLimit lives, write() fails with
/// EFBIG once a file of this process would pass `bytes` (RLIMIT_FSIZE), and SIGXFSZ is ignored
/// so the failure is an error, not a kill. Restores both when it goes.

#include <signal.h>
#include <sys/resource.h>

namespace vh::test {

class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    old_handler_ = ::signal(SIGXFSZ, SIG_IGN);
    ::getrlimit(RLIMIT_FSIZE, &old_);
    const rlimit limit{bytes, old_.rlim_max};
    ::setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &old_);
    ::signal(SIGXFSZ, old_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  rlimit old_{};
  sighandler_t old_handler_ = nullptr;
};

}  // namespace vh::test
