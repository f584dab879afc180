#pragma once
// The files that describe a unit's triads (inertia-analyze unit writes them, export writes them
// on request): unit.toml (unit_model.hpp names its members' model files in it), imucal's
// calibration file and Kalibr's scale-misalignment results.
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

#include "analyzer/model/model_file.hpp"
#include "analyzer/unit/triad_frame.hpp"

namespace inertia::unit {

struct UnitParameter;   // unit_covariance.hpp

/// A unit's members by kind, and each triad given.
struct Triads {
  std::vector<model::ModelFile> accelerometers, gyroscopes;
  std::optional<TriadFrame> accelerometer, gyroscope;
  [[nodiscard]] const TriadFrame& any() const;
};

/// The triads of `members` (three or six, any order). Throws InputError as triad_frame does, or for
/// triads of two units.
Triads triads_of(const std::vector<model::ModelFile>& members);

/// unit.toml's text: the unit, and per triad K, R, b with their sd, the non-orthogonality with its
/// sd, dof and 95 % interval, each axis's sensitivity, covariance and member model file; then the
/// covariance of every parameter of imucal's and Kalibr's: `parameters`, unit_parameters(triads).
std::string unit_toml(const Triads& triads, const std::vector<UnitParameter>& parameters);

/// imucal's calibration file (FerrarisCalibrationInfo, format 2.0.0): calibrated = R^-1 K^-1 (raw - b),
/// the gyroscope's offset K_ga acc + b_g. A triad not given is null, and the comment says so.
nlohmann::json imucal_json(const Triads& triads);

/// The covariance of each of imucal's and Kalibr's parameters (`parameters`, unit_parameters of
/// the triads): an object of name to value and covariance (arrays of rows) and, for Kalibr's
/// rotations, "rotation": true.
nlohmann::json covariance_json(const std::vector<UnitParameter>& parameters);

/// Kalibr's results for an IMU of its scale-misalignment model (kalibr_intrinsics.hpp), with each
/// kind's noise parameters: the largest of the triad's members, so that none is claimed quieter
/// than it is. Each matrix's sd, from `parameters` (unit_parameters(triads)), as a comment.
std::string kalibr_yaml(const Triads& triads, const std::vector<UnitParameter>& parameters);

}  // namespace inertia::unit
