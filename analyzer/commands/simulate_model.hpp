#pragma once
// simulate --model: the bench's plan simulated as `simulate` does (references, thermal, the
// bench's fixture misalignments), with a sensor's output then computed from a model file instead
// of the bench's truth parameters. The model's own misalignment M_C^S replaces the sensor's; its
// terms (squares' high pass included) are run free on the simulated references (lagged outputs
// fed back, noise terms zero) and white noise of the model's white_sd is added, seeded from the
// sensor's seed. truth.toml then holds the model's terms, its M_C^S and each case's M_E^S, so
// that characterize on the result is scored against the model: the round trip of a model file.
#include <filesystem>
#include <map>
#include <optional>
#include <cstdint>
#include <ostream>
#include <string>

namespace inertia::commands {

struct SimulateOptions {
  std::filesystem::path bench;
  std::filesystem::path out;
  /// Sensor name -> model file; the key "" names the bench's only sensor.
  std::map<std::string, std::filesystem::path> models;
  std::optional<std::uint64_t> seed;   // another run of the bench: every random stream from it
};

/// InputError for a model of another sensor kind than the bench's sensor, a sensor the bench
/// lacks, an empty key on a bench of several sensors, or a model the simulation cannot run free
/// (procedure::simulate_model's reasons).
int run_simulate(const SimulateOptions& options, std::ostream& summary);

}  // namespace inertia::commands
