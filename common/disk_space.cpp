#include "common/disk_space.hpp"

#include <fmt/format.h>

#include "common/input_error.hpp"

namespace inertia {
namespace {

std::filesystem::path nearest_existing(std::filesystem::path path) {
  path = std::filesystem::absolute(path);
  while (!std::filesystem::exists(path) && path.has_parent_path() && path.parent_path() != path) path = path.parent_path();
  return path;
}

std::string megabytes(std::uintmax_t bytes) { return fmt::format("{:.1f} MB", static_cast<double>(bytes) / 1e6); }

}  // namespace

std::uintmax_t free_bytes_for(const std::filesystem::path& path) {
  return std::filesystem::space(nearest_existing(path)).available;
}

void require_free_space(const std::filesystem::path& path, std::uintmax_t bytes, std::string_view what) {
  const std::filesystem::path at = nearest_existing(path);
  const std::uintmax_t available = std::filesystem::space(at).available;
  if (bytes <= available) return;
  throw InputError(fmt::format("{}: about {} to write, and the filesystem of {} has {} free; nothing was written",
                               what, megabytes(bytes), at.string(), megabytes(available)));
}

}  // namespace inertia
