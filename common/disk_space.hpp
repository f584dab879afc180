#pragma once
// Room on the disk for an output before it is written: a writer whose output grows with the
// record (a dataset's CSVs) asks first, and is refused with the figures instead of filling the
// disk and failing part way.
#include <cstdint>
#include <filesystem>
#include <string_view>

namespace inertia {

/// The bytes free to this process on the filesystem that `path` is, or would be, created on (its
/// nearest existing ancestor's).
std::uintmax_t free_bytes_for(const std::filesystem::path& path);

/// Throws InputError naming `what`, the bytes it needs and the bytes free, when `bytes` exceed
/// free_bytes_for(path).
void require_free_space(const std::filesystem::path& path, std::uintmax_t bytes, std::string_view what);

}  // namespace inertia
