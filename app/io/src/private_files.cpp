// Owner-only files and folders (vh/io/private_files.h).
#include "vh/io/private_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>
#include <stdexcept>
#include <vector>

namespace vh::io {

namespace fs = std::filesystem;

namespace {

std::string reason(int error) { return std::strerror(error); }

}  // namespace

void createPrivateDirectories(const fs::path& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return;
  const fs::path parent = dir.parent_path();
  if (!parent.empty() && parent != dir) createPrivateDirectories(parent);
  if (::mkdir(dir.c_str(), 0700) != 0) {
    const int error = errno;
    if (error == EEXIST && fs::is_directory(dir, ec)) return;  // created meanwhile
    throw std::runtime_error("cannot create the folder " + dir.string() + ": " + reason(error));
  }
  // mkdir's mode is masked by the umask; 0700 needs no bit the umask could add, but a umask
  // that removes owner bits (0700 itself) would make it unusable: set it explicitly.
  ::chmod(dir.c_str(), 0700);
}

int openPrivateFile(const fs::path& path, bool append) {
  const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | (append ? O_APPEND : O_TRUNC);
  const int fd = ::open(path.c_str(), flags, 0600);
  if (fd < 0) throw std::runtime_error("cannot create " + path.string() + ": " + reason(errno));
  if (::fchmod(fd, 0600) != 0) {
    const int error = errno;
    ::close(fd);
    throw std::runtime_error("cannot make " + path.string() + " private: " + reason(error));
  }
  return fd;
}

void createPrivateFile(const fs::path& path) { ::close(openPrivateFile(path)); }

void makePrivate(const fs::path& path) {
  if (::chmod(path.c_str(), 0600) != 0) {
    throw std::runtime_error("cannot make " + path.string() + " private: " + reason(errno));
  }
}

bool namesStandardOutput(const fs::path& target) {
  const std::string named = target.string();
  return named == "-" || named == "/dev/stdout" || named == "/dev/fd/1";
}

PrivateOutput::PrivateOutput(fs::path target) : target_(std::move(target)) {
  // The standard streams by name: written to, never replaced (they are links into /proc).
  const std::string named = target_.string();
  if (namesStandardOutput(target_)) {
    temp_ = "/dev/stdout";
    standard_ = &std::cout;
    in_place_ = true;
    return;
  }
  if (named == "/dev/stderr" || named == "/dev/fd/2") {
    temp_ = "/dev/stderr";
    standard_ = &std::cerr;
    in_place_ = true;
    return;
  }
  struct stat st {};
  if (::lstat(target_.c_str(), &st) == 0) {
    if (S_ISLNK(st.st_mode))
      throw std::runtime_error("will not write " + named +
                               ": it is a symbolic link (not followed, not replaced); name the file it points to");
    if (S_ISDIR(st.st_mode)) throw std::runtime_error("cannot write " + named + ": it is a folder");
    if (!S_ISREG(st.st_mode)) {  // a FIFO, a device, a socket: written in place, never replaced
      temp_ = target_;
      in_place_ = true;
      return;
    }
  }
  const fs::path folder = target_.has_parent_path() ? target_.parent_path() : fs::path(".");
  const std::string ext = target_.extension().string();
  std::string leaf(1, '.');  // hidden, named after the target, with its extension
  leaf.append(target_.stem().string()).append(".XXXXXX").append(ext);
  const std::string pattern = (folder / leaf).string();
  std::vector<char> name(pattern.begin(), pattern.end());
  name.push_back('\0');
  const int fd = ::mkstemps(name.data(), static_cast<int>(ext.size()));
  if (fd < 0) throw std::runtime_error("cannot write " + target_.string() + ": " + reason(errno));
  ::fchmod(fd, 0600);
  ::close(fd);
  temp_ = fs::path(name.data());
}

PrivateOutput::~PrivateOutput() {
  if (in_place_) {  // the target itself: never removed
    if (stream_.is_open()) stream_.close();
    return;
  }
  if (committed_) return;
  if (stream_.is_open()) stream_.close();
  std::error_code ec;
  fs::remove(temp_, ec);
}

std::ostream& PrivateOutput::stream() {
  if (standard_ != nullptr) return *standard_;
  // In place: no truncation (a FIFO or device has nothing to truncate; a stream is appended to).
  if (!stream_.is_open()) stream_.open(temp_, in_place_ ? std::ios::binary | std::ios::out : std::ios::binary | std::ios::trunc);
  return stream_;
}

void PrivateOutput::commit() {
  const auto fail = [&](const std::string& why) {
    if (stream_.is_open()) stream_.close();
    std::error_code ec;
    if (!in_place_) fs::remove(temp_, ec);
    committed_ = true;  // nothing left to remove
    throw std::runtime_error("cannot write " + target_.string() + ": " + why);
  };
  if (committed_) return;
  if (stream_.is_open()) {
    stream_.flush();
    const bool good = stream_.good();
    stream_.close();
    if (!good || stream_.fail()) fail("write failed (disk full?)");
  }
  if (standard_ != nullptr) {
    standard_->flush();
    if (!standard_->good()) {
      standard_->clear();
      fail("write failed (disk full, or the reader went away?)");
    }
  }
  if (in_place_) {
    committed_ = true;
    return;
  }
  std::error_code ec;
  if (!fs::exists(temp_, ec)) fail("the temporary file vanished");
  if (::chmod(temp_.c_str(), 0600) != 0) fail(reason(errno));
  if (::rename(temp_.c_str(), target_.c_str()) != 0) fail(reason(errno));
  committed_ = true;
}

}  // namespace vh::io
