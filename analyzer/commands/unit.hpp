#pragma once
// `inertia-analyze unit --model M.toml ... --out DIR`: the triads of a unit (unit/triad_frame.hpp)
// from its members' model files, three of one kind or six (an accelerometer and a gyroscope
// triad): the sensitive axes in the unit's frame, their non-orthogonality, the scale-and-
// misalignment matrix and bias vector in imucal's convention (K, R, b) with standard
// uncertainties, and for gyroscopes the g-sensitivity K_ga. Writes DIR/unit.toml and
// DIR/imucal.json (imucal's calibration file, format 2.0.0; a triad not characterized is null
// there, and its comment says so).
#include <filesystem>
#include <iosfwd>
#include <vector>

namespace inertia::commands {

int run_unit(const std::vector<std::filesystem::path>& models, const std::filesystem::path& out, std::ostream& summary);

}  // namespace inertia::commands
