#pragma once
// `inertia-analyze simulate --bench CONFIG --out DIR`: runs the bench file's test plan through the
// simulated bench and writes a dataset folder (docs/design.md, "Dataset folder") per sensor under test:
// with one [[sensor]], OUT itself; with several, OUT/<sensor-name>/. Each dataset folder also gets
// truth.toml: the truth parameters ([params]), the equivalent model terms in the model-file form
// (sensor, m_cs, [terms], [noise]) and per case the true orientation chain ([[case]]).
// The reference instruments of every case go to OUT/references/<case>.csv.
#include <filesystem>
#include <cstdint>
#include <iosfwd>
#include <optional>

#include "common/config/bench_config.hpp"
#include "common/dataset/dataset.hpp"
#include "hal/sim/bench_simulation.hpp"

namespace inertia::sim {

/// Loads, simulates, writes and prints a summary. With `seed`, another run of the same bench
/// (config::reseed: every random stream from it), as held-out data is. Returns kExitOk; bad input
/// throws InputError (the caller maps it to exit status 2).
int run_simulate(const std::filesystem::path& bench, const std::filesystem::path& out, std::ostream& summary,
                 std::optional<std::uint64_t> seed = std::nullopt);

/// The dataset (docs/design.md contract, in memory) of sensor under test `sensor_index`: nominal m_ec,
/// the references it saw, its output. write_simulation writes exactly this.
dataset::Dataset sensor_dataset(const config::BenchConfig& bench, const BenchSimulation& sim, std::size_t sensor_index);

/// Writes the dataset folders, truth files and reference CSVs of a finished simulation.
void write_simulation(const config::BenchConfig& bench, const BenchSimulation& sim, const std::filesystem::path& out);

/// One block per case: kind, samples, duration, phases, ranges of f_E (in g) and of each output.
void print_summary(const config::BenchConfig& bench, const BenchSimulation& sim, std::ostream& os);

}  // namespace inertia::sim
