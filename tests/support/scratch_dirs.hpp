#pragma once
// Scratch places for tests that need real files and real disks: a fresh directory, and a small
// tmpfs that really fills (ENOSPC) for the full-disk tests of the log writer and the daemon.
#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>

namespace inertia::testing {

/// A fresh directory under the temp directory, removed with everything in it by the destructor.
struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& prefix = "inertia-test") {
    std::string tmpl = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
    path = ::mkdtemp(tmpl.data());
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

/// A tmpfs of `size` (mount syntax, e.g. "2m") mounted at `where`; unmounted before its directory
/// goes. Needs root: `why_not` says why it is not mounted (the test then skips).
struct SmallDisk {
  std::filesystem::path path;
  std::string why_not;  // empty when mounted
  SmallDisk(const std::filesystem::path& where, const char* size) : path(where) {
    std::filesystem::create_directories(path);
    const std::string options = std::string("size=") + size;
    if (::geteuid() != 0) {
      why_not = "not root: cannot mount a small tmpfs to fill";
    } else if (::mount("tmpfs", path.c_str(), "tmpfs", 0, options.c_str()) != 0) {
      why_not = std::string("mount tmpfs: ") + std::strerror(errno);
    }
  }
  SmallDisk(const SmallDisk&) = delete;
  SmallDisk& operator=(const SmallDisk&) = delete;
  ~SmallDisk() {
    if (why_not.empty()) (void)::umount2(path.c_str(), MNT_DETACH);
  }
};

}  // namespace inertia::testing
