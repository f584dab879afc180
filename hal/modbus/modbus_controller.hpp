#pragma once
// A Modbus-attached bench controller (thermal fixture, rotation table, shaker status): polls a
// register map into named values with validity, and writes setpoints only when the config
// enables writes, clamped to the register's limits, rate-limited, and confirmed by reading the
// register back.
// Thread: the daemon's Modbus thread (not real-time; each call may block up to the response
// timeout per request). poll() allocates nothing after connect().
#include <cstdint>
#include <memory>
#include <optional>
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
  bool valid = false;      // false when its request failed (see link().health()), it held no
                           // reading (NaN or infinity, register_map.hpp decode_reading), or
                           // the reading is outside the register's plausible range
  bool out_of_range = false;  // answered, but outside [range_min, range_max] (value kept)
  std::int64_t t_ns = 0;   // CLOCK_MONOTONIC when the answer arrived
};

/// NotConfirmed: written, but reading the register back gave other words (read_back says what
/// the device holds; NaN when the read itself failed): the controller did not take the value.
enum class WriteStatus { Written, Disabled, NotWritable, UnknownRegister, NotFinite, LinkError, NotConfirmed };
const char* to_string(WriteStatus status) noexcept;

struct WriteResult {
  WriteStatus status = WriteStatus::Disabled;
  double written = 0.0;    // the SI value the device now holds (after clamping, rate limit and quantisation)
  bool clamped = false;    // the request was outside [min, max]
  bool rate_limited = false;  // written is a step toward the request: write again to go on
  double read_back = 0.0;  // the SI value read back after the write (== written when confirmed)
};

/// How a write may move a setpoint: Limited by the register's max_rate (every plan command), or
/// Immediate (the safe state on an abort: a stop must not be ramped; the controller's own
/// deceleration limits apply).
enum class Ramp { Limited, Immediate };

class ModbusController {
 public:
  static constexpr int kMaxWordsPerRequest = 125;  // Modbus limit for FC3/FC4
  /// A rate-limited write moves at most max_rate x this far after a long pause: the setpoint
  /// changes in steps of at most a tenth of a second's worth, however seldom it is written.
  static constexpr double kMaxRampStepS = 0.1;

  /// nullptr with the reason when the config is invalid or the first connect fails.
  static std::unique_ptr<ModbusController> connect(const ModbusConfig& config, std::string* why);

  /// Reads every register, grouping contiguous ones of one kind into a request each.
  /// Values of a failed request are marked invalid; others stay valid.
  std::span<const PolledValue> poll();
  /// Writes one setpoint. Disabled unless config.writes_enabled; NotWritable unless the register
  /// is; otherwise clamped to [min, max], with Ramp::Limited moved toward the value by at most
  /// max_rate x min(time since this register's previous write, kMaxRampStepS) (from the value
  /// read from the device before its first write), quantised to the register's type, written,
  /// and read back: Written only when the device holds exactly the words written.
  WriteResult write(std::string_view name, double value, Ramp ramp = Ramp::Limited);
  WriteResult write(std::size_t register_index, double value, Ramp ramp = Ramp::Limited);

  [[nodiscard]] std::span<const PolledValue> values() const noexcept { return values_; }
  [[nodiscard]] const ModbusConfig& config() const noexcept { return config_; }
  /// Readings outside their register's plausible range, since connect().
  [[nodiscard]] std::uint64_t range_faults() const noexcept { return range_faults_; }
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
  // Per register: the value of its last confirmed write and when (for the rate limit).
  std::vector<std::optional<double>> last_written_;
  std::vector<std::int64_t> last_write_ns_;
  std::uint64_t range_faults_ = 0;
};

}  // namespace inertia::hal::modbus
