#pragma once
// Modbus register maps in plain structs (filled from the bench TOML by common/config), and the
// conversion between register words and SI values. Everything here is pure and real-time safe
// except is_valid().
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace inertia::hal::modbus {

enum class RegisterKind { Holding, Input };            // FC3 / FC4 (writes: FC6 / FC16)
enum class DataType { UInt16, Int16, UInt32, Int32, Float32 };
/// Order of the four bytes A (most significant) .. D of a 32-bit value across two registers,
/// as libmodbus names them (modbus_get_float_abcd ...): ABCD = high word first, big-endian
/// words (Modbus "standard"); CDAB = low word first (word swap); BADC = byte swap in each word;
/// DCBA = both. Ignored for 16-bit types.
enum class WordOrder { ABCD, CDAB, BADC, DCBA };

struct RegisterSpec {
  std::string name;
  int address = 0;                 // protocol address (0-based), as on the device's table
  RegisterKind kind = RegisterKind::Holding;
  DataType type = DataType::UInt16;
  WordOrder order = WordOrder::ABCD;
  double scale = 1.0;              // value (SI) = scale * raw + offset
  double offset = 0.0;
  bool writable = false;           // a setpoint; also needs ModbusConfig::writes_enabled
  double min = -std::numeric_limits<double>::infinity();  // write limits, SI
  double max = std::numeric_limits<double>::infinity();
  // Rate limit of a setpoint, SI per second: a write moves the register toward the value asked
  // by at most max_rate x the time since its previous write (ModbusController::write).
  double max_rate = std::numeric_limits<double>::infinity();
  // Plausible readings, SI: a poll that reads a value outside marks it invalid, a range fault.
  double range_min = -std::numeric_limits<double>::infinity();
  double range_max = std::numeric_limits<double>::infinity();
};

struct RegisterMap {
  std::vector<RegisterSpec> registers;
  /// False with a reason naming the register ("register 'setpoint': writable on an input register").
  bool is_valid(std::string* why) const;
  /// Index of a register by name, or -1. Non-RT (string compare).
  [[nodiscard]] int find(std::string_view name) const noexcept;
};

/// Registers a value of this type occupies (1 or 2).
int word_count(DataType type) noexcept;
/// SI value from the words at the register's address (words.size() >= word_count).
double decode(const RegisterSpec& spec, std::span<const std::uint16_t> words) noexcept;
/// The register as a sample: its SI value, or nullopt when the words hold no reading. A float32
/// NaN or infinity is what a controller sends for a broken or absent sensor, and a scale can
/// carry a large raw value past the double range; either pushed as a valid sample would poison
/// every estimate downstream. Real-time safe.
std::optional<double> decode_reading(const RegisterSpec& spec, std::span<const std::uint16_t> words) noexcept;
/// Words for an SI value: raw = round((value - offset) / scale), saturated to the type's range.
/// Returns the SI value the words stand for (what the device will hold).
double encode(const RegisterSpec& spec, double value, std::span<std::uint16_t> words) noexcept;

}  // namespace inertia::hal::modbus
