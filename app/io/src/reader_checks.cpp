// Reader pre-checks (reader_checks.h).
#include "reader_checks.h"

#include <sys/stat.h>

#include "loader_internal.h"
#include "vh/io/available_memory.h"

namespace vh::io::detail {

void requireBesideHeader(const fs::path& header, const fs::path& data_file) {
  std::error_code ec;
  const fs::path folder = fs::weakly_canonical(fs::absolute(header, ec).parent_path(), ec);
  const fs::path target = fs::weakly_canonical(fs::absolute(data_file, ec), ec);
  const fs::path rel = target.lexically_relative(folder);
  const bool inside = !ec && !rel.empty() && *rel.begin() != ".." && rel.is_relative();
  if (!inside) {
    fail(header, "the data file " + data_file.string() + " lies outside the header's folder " + folder.string() +
                     " (resolved to " + target.string() + "); detached data files are read only beside their header");
  }
}

void requireRegularFile(const fs::path& path, const fs::path& named_by) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) fail(named_by, path == named_by ? "no such file" : "data file " + path.string() + " is missing");
  if (!S_ISREG(st.st_mode)) {
    const char* kind = S_ISFIFO(st.st_mode)                          ? "a FIFO"
                       : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "a device"
                       : S_ISDIR(st.st_mode)                        ? "a folder"
                                                                     : "not a regular file";
    fail(named_by, (path == named_by ? std::string("it is ") : "data file " + path.string() + " is ") + kind +
                       ", not a regular file: nothing was read");
  }
}

void requireDeclaredFits(const fs::path& path, std::uint64_t bytes) {
  if (fitsInMemory(bytes)) return;
  fail(path, "declares " + formatBytes(bytes) + " of voxels but " + formatBytes(availableMemoryBytes().value_or(0)) +
                 " of memory is available (" + formatBytes(kMemoryMargin_bytes) + " kept free): not read");
}

}  // namespace vh::io::detail
