#pragma once
// Devices of a real bench ([[can_device]], [[gpiod_encoder]], [[modbus_device]] in the bench
// file), translated one to one into the HAL's structs and opened. The bench file has no
// "optional" flag for a device, so every configured device is required: the first one that
// cannot be opened stops the start with its name and the reason (exit status 2).
#include <memory>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "daq/sampler.hpp"

namespace inertia::daq {

/// nullptr-free vector of samplers, or empty + why naming the device that failed. Control thread.
std::vector<std::unique_ptr<Sampler>> open_real_bench(const config::BenchConfig& bench, std::size_t ring_capacity,
                                                      std::string* why);

}  // namespace inertia::daq
