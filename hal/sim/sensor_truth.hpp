#pragma once
// The truth parameters of simulated sensors under test: from [sensor.truth] (same names as the
// fields of AccelerometerParams / FogParams) to the structs, and back out as truth.toml with the
// equivalent model terms in the model-file form of docs/design.md ("Model file").
#include <toml++/toml.h>

#include "common/config/bench_config.hpp"
#include "hal/sim/sensors/accelerometer_model.hpp"
#include "hal/sim/sensors/fog_model.hpp"

namespace inertia::sim {

/// Starts from the struct defaults (the paper's table 1 for accelerometers) and applies every
/// [sensor.truth] entry. Throws InputError at the entry's line and column for an unknown name,
/// a scalar given for an array or the reverse, or a wrong array length.
AccelerometerParams accelerometer_params(const config::SensorUnderTest& sensor);
FogParams fog_params(const config::SensorUnderTest& sensor);

/// Every field, by its config name.
toml::table to_toml(const AccelerometerParams& p);
toml::table to_toml(const FogParams& p);

/// Equation 12 as model terms with SI inputs (accelerometer_model_terms, the truth model's own
/// conversion); `notes` says which terms are high-pass (listed with their high-frequency gain).
toml::table model_terms(const AccelerometerParams& p, toml::table* notes);
/// Equation 5 solved for the output Omega: linear terms over S0, the output-multiplied terms
/// y*T = -1e-6 eps_T and y*w_i = -c_f1; g-sensitivity transfer functions by their static gain.
toml::table model_terms(const FogParams& p, toml::table* notes);

toml::array to_toml(const Eigen::Matrix3d& m);

}  // namespace inertia::sim
