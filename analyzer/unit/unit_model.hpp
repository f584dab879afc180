#pragma once
// A unit's model: the folder `inertia-analyze unit` writes. unit.toml holds the triads in the
// unit's frame (triad_frame.hpp) and names, for each member, its model file, copied beside it:
//
//   unit = "imu1"
//   serial = "IMU-0001"
//   [accelerometer.axis.x]
//   sensor = "ax"
//   model = "member-ax.toml"
//
// So the folder is the whole unit: the per-output models (nonlinear, lagged, with their
// covariance) that compensation inverts jointly, and the matrices other tools read.
#include <filesystem>
#include <string>
#include <vector>

#include "analyzer/model/model_file.hpp"

namespace inertia::unit {

struct UnitModel {
  std::filesystem::path file;
  std::string unit, serial;
  /// The members: the accelerometers along x, y, z, then the gyroscopes, of the triads present.
  std::vector<model::ModelFile> members;
  [[nodiscard]] bool has(dataset::SensorKind kind) const;
};

/// The member model file's name in a unit's folder.
std::string member_file_name(const std::string& sensor);

/// Whether `file` is a unit.toml (a top-level `unit` and no [terms]) rather than one output's
/// model file. Reads the file; false when it cannot be parsed (the model reader then says why).
bool is_unit_model(const std::filesystem::path& file);

/// Reads unit.toml and its members' model files. Throws InputError (file, what) for a member
/// file that is missing or not of this unit, kind and axis, or a triad without all three.
UnitModel read_unit_model(const std::filesystem::path& file);

}  // namespace inertia::unit
