#include "common/output_folder.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <system_error>

#include "common/atomic_file.hpp"
#include "common/input_error.hpp"

namespace inertia {

namespace {

namespace fs = std::filesystem;

constexpr std::string_view kIncomplete = ".incomplete-";
constexpr std::string_view kReplaced = ".replaced-";

/// A path made absolute and without a trailing separator, so that its parent is the folder that
/// holds it (`out/` would otherwise name `out` as its own parent).
fs::path normalized(const fs::path& p) {
  fs::path a = fs::absolute(p).lexically_normal();
  if (!a.has_filename() && a.has_parent_path()) a = a.parent_path();
  return a;
}

bool process_alive(pid_t pid) { return ::kill(pid, 0) == 0 || errno == EPERM; }

/// Removes TARGET.incomplete-<pid> and TARGET.replaced-<pid> folders whose process has ended:
/// the leftovers of runs into `target` that were stopped.
void remove_stale_staging(const fs::path& target) {
  std::error_code ec;
  const std::string name_of_target = target.filename().string();
  for (const fs::directory_entry& e : fs::directory_iterator(target.parent_path(), ec)) {
    const std::string name = e.path().filename().string();
    for (const std::string_view kind : {kIncomplete, kReplaced}) {
      const std::string prefix = name_of_target + std::string(kind);
      if (!name.starts_with(prefix)) continue;
      char* end = nullptr;
      const long pid = std::strtol(name.c_str() + prefix.size(), &end, 10);
      if (end != name.c_str() + prefix.size() && *end == '\0' && pid > 0 && !process_alive(static_cast<pid_t>(pid)))
        fs::remove_all(e.path(), ec);
    }
  }
}

}  // namespace

OutputFolder::OutputFolder(std::filesystem::path target, std::string verb) : target_(normalized(target)), verb_(std::move(verb)) {
  if (!target_.has_filename() || target_ == target_.root_path())
    throw InputError(fmt::format("--out {}: not a folder that can be replaced", target.string()));
  std::error_code ec;
  if (fs::exists(target_, ec)) {
    if (!fs::is_directory(target_, ec)) throw InputError(fmt::format("--out {}: exists and is not a folder", target.string()));
    if (!fs::is_empty(target_, ec) && !fs::exists(target_ / kMarker, ec)) {
      throw InputError(fmt::format("--out {}: the folder holds files inertia did not write (no {}); a run replaces its output "
                                   "folder whole, so give a new or empty folder, or one an earlier run wrote",
                                   target.string(), kMarker));
    }
  }
  fs::create_directories(target_.parent_path());
  remove_stale_staging(target_);
  staging_ = target_;
  staging_ += fmt::format("{}{}", kIncomplete, ::getpid());
  fs::remove_all(staging_);   // this process's own earlier staging (a run that threw before its destructor ran)
  fs::create_directory(staging_);
}

OutputFolder::~OutputFolder() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

std::filesystem::path OutputFolder::final_path(const std::filesystem::path& file) const {
  const fs::path relative = normalized(file).lexically_relative(staging_);
  return relative.empty() || *relative.begin() == ".." ? file : target_ / relative;
}

void OutputFolder::commit() {
  const std::time_t now = std::time(nullptr);
  char when[32] = {};
  std::strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  write_file_atomically(staging_ / kMarker, fmt::format("written by inertia-analyze {} at {}; the next run into this folder "
                                                        "replaces it whole\n",
                                                        verb_, when));
  std::error_code ec;
  if (!fs::exists(target_, ec)) {
    fs::rename(staging_, target_);
  } else if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, target_.c_str(), RENAME_EXCHANGE) == 0) {
    fs::remove_all(staging_);   // it now holds the previous output
  } else if (errno == EINVAL || errno == ENOSYS || errno == EOPNOTSUPP) {
    // A filesystem without the exchange: the previous output moves aside first. A stop between
    // the two renames leaves TARGET absent and both folders beside it, neither taken as complete.
    fs::path previous = target_;
    previous += fmt::format("{}{}", kReplaced, ::getpid());
    fs::rename(target_, previous);
    fs::rename(staging_, target_);
    fs::remove_all(previous);
  } else {
    throw std::system_error(errno, std::generic_category(), fmt::format("cannot put {} in place of {}", staging_.string(), target_.string()));
  }
  committed_ = true;
}

}  // namespace inertia
