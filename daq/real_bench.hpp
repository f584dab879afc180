#pragma once
// Devices of a real bench ([[can_device]], [[gpiod_encoder]], [[modbus_device]] in the bench
// file), translated one to one into the HAL's structs and opened. A required device that
// cannot be opened stops the start: it is named with its bench-file position, the reason and
// the command that fixes it (the diagnosis of inertia-daqd --check, device_check.hpp), exit 2.
// An `optional = true` device that cannot be opened is left out and the bench runs degraded.
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "daq/controller_port.hpp"
#include "daq/life_sign.hpp"
#include "daq/sampler.hpp"
#include "hal/gpiod/encoder_device.hpp"
#include "hal/modbus/modbus_link.hpp"
#include "hal/socketcan/can_device.hpp"

namespace inertia::daq {

/// An optional device the daemon runs without, and why (one line, with the fix).
struct LeftOutDevice {
  std::string name;
  std::string why;
};

struct RealBench {
  std::vector<std::unique_ptr<Sampler>> samplers;   // every device that opened
  std::vector<LeftOutDevice> left_out;              // optional devices that did not
  /// Per Modbus device that opened (by name): the test executive's way to it, served by its
  /// polling thread. Safe values are those of registers with `safe` on a device with writes enabled.
  std::map<std::string, std::shared_ptr<ControllerPort>> ports;
};

/// The opened bench, or empty samplers + why naming the required device that failed (or that
/// there are no devices at all). `life`: the daemon's proof of life, which each controller's
/// heartbeat follows. Control thread.
RealBench open_real_bench(const config::BenchConfig& bench, std::size_t ring_capacity, std::shared_ptr<const LifeSign> life,
                          std::string* why);

// The bench file's device tables in the HAL's terms (also used by device_check.cpp).
hal::socketcan::CanDeviceConfig to_hal(const config::CanDevice& device);
hal::gpiod::QuadratureConfig to_hal(const config::GpiodEncoder& encoder, double bench_sample_rate_hz);
hal::modbus::ModbusConfig to_hal(const config::ModbusDevice& device);

}  // namespace inertia::daq
