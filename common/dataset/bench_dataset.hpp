#pragma once
// A sensor's dataset as its bench states it: the header fields a dataset folder carries (kind,
// names, serial, part, unit, output unit, T's reference), without cases. The simulator and an
// event log's fusion both start their datasets here, so the two agree field for field.
#include <cstddef>

#include "common/config/bench_config.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::dataset {

/// The header of bench.sensors[sensor_index]'s dataset; no cases.
Dataset bench_sensor_dataset(const config::BenchConfig& bench, std::size_t sensor_index);

}  // namespace inertia::dataset
