#pragma once
// `inertia-analyze unit --model X.toml --model Y.toml --model Z.toml --out DIR`: the triad of a
// unit (unit/triad_frame.hpp) from its three members' model files: the sensitive axes in the
// unit's frame, their non-orthogonality, and the scale-and-misalignment matrix and bias vector in
// imucal's convention (K, R, b), each with its standard uncertainty. Writes DIR/unit.toml.
#include <filesystem>
#include <iosfwd>
#include <vector>

namespace inertia::commands {

int run_unit(const std::vector<std::filesystem::path>& models, const std::filesystem::path& out, std::ostream& summary);

}  // namespace inertia::commands
