#pragma once
// A Modbus-attached bench controller (thermal fixture, rotation table, shaker status): polls a
// register map into named values with validity, and writes setpoints only when the config
// enables writes, clamped to the register's limits.
// Thread: the daemon's Modbus thread (not real-time; each call may block up to the response
// timeout per request). poll() allocates nothing after connect().
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "hal/modbus/modbus_link.hpp"
#include "hal/modbus/register_map.hpp"

namespace inertia::hal::modbus {

struct PolledValue {
  std::string_view name;   // the register's name (points into the controller's config)
  double value = 0.0;      // SI; meaningless when !valid
  bool valid = false;      // false when its request failed (see link().health()) or it held no
                           // reading (NaN or infinity, register_map.hpp decode_reading)
  std::int64_t t_ns = 0;   // CLOCK_MONOTONIC when the answer arrived
};

enum class WriteStatus { Written, Disabled, NotWritable, UnknownRegister, NotFinite, LinkError };
const char* to_string(WriteStatus status) noexcept;

struct WriteResult {
  WriteStatus status = WriteStatus::Disabled;
  double written = 0.0;    // the SI value the device now holds (after clamping and quantisation)
  bool clamped = false;    // the request was outside [min, max]
};

class ModbusController {
 public:
  static constexpr int kMaxWordsPerRequest = 125;  // Modbus limit for FC3/FC4

  /// nullptr with the reason when the config is invalid or the first connect fails.
  static std::unique_ptr<ModbusController> connect(const ModbusConfig& config, std::string* why);

  /// Reads every register, grouping contiguous ones of one kind into a request each.
  /// Values of a failed request are marked invalid; others stay valid.
  std::span<const PolledValue> poll();
  /// Writes one setpoint. Disabled unless config.writes_enabled; NotWritable unless the register
  /// is; otherwise clamped to [min, max], quantised to the register's type, written.
  WriteResult write(std::string_view name, double value);

  [[nodiscard]] std::span<const PolledValue> values() const noexcept { return values_; }
  [[nodiscard]] const ModbusConfig& config() const noexcept { return config_; }
  [[nodiscard]] ModbusLink& link() noexcept { return *link_; }

 private:
  struct Block {
    RegisterKind kind;
    int address;
    int words;
    std::vector<std::size_t> registers;  // indices into config_.map.registers
  };
  ModbusController(ModbusConfig config, std::unique_ptr<ModbusLink> link);

  ModbusConfig config_;
  std::unique_ptr<ModbusLink> link_;
  std::vector<Block> blocks_;
  std::vector<PolledValue> values_;
  std::vector<std::uint16_t> words_;
};

}  // namespace inertia::hal::modbus
