#pragma once
// `inertia-analyze export --model M.toml --format c|json|kalibr|imucal --out DIR`: a characterized model
// in the forms the sensor's users read.
//   c       P.h and P.c: the compensation as C99 for firmware (compensate/c_export.hpp), float or
//           double; with --vectors DATASET also P_vectors.csv, the analyzer's answers on that
//           record's first case for the code to be checked against.
//   json    model.json: the whole model (terms with physical names, coefficients, covariance,
//           range, frames, noise) against tests/schema/model.schema.json.
//   kalibr  imu.yaml: Kalibr's IMU noise parameters (continuous-time noise density and random
//           walk, in Kalibr's units, from the model's N and K over its static sensitivity).
// A format that cannot hold a term says so: the summary and the file name every term left out
// and the largest error that costs over the characterized range (static_response.hpp).
// With a unit's unit.toml (inertia-analyze unit): c (the outputs solved together, generate_joint_c;
// --vectors takes the folder of the members' datasets), imucal (imucal.json), kalibr (imu.yaml
// with the scale-misalignment intrinsics and noise) or json (unit.json: each member's model and
// the triads).
#include <filesystem>
#include <iosfwd>
#include <string>

namespace inertia::commands {

struct ExportOptions {
  std::filesystem::path model;
  std::string format;              // c | json | kalibr | imucal (a unit)
  std::filesystem::path out;       // a folder
  std::string prefix;              // c: the generated names' prefix (default: the sensor's name, else "inertia_model")
  bool single_precision = false;   // c: float instead of double
  std::filesystem::path vectors;   // c: a dataset folder to write test vectors from
  long vector_samples = 5000;
};

int run_export(const ExportOptions& options, std::ostream& out);

}  // namespace inertia::commands
