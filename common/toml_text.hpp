#pragma once
// Writing TOML by hand (dataset.toml, model files): values that read back bit for bit.
#include <string>
#include <string_view>

namespace inertia {

/// A TOML basic string with the escapes the spec requires.
std::string toml_quote(std::string_view s);

/// A TOML float: the shortest digits that round-trip, with ".0" added when they would read as an
/// integer. Non-finite values print as nan/inf, which TOML accepts; callers that must refuse them
/// check first.
std::string toml_float(double v);

}  // namespace inertia
