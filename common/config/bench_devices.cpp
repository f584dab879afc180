// The bench file's devices of a real bench: CAN devices and their signals ([[can_device]]), GPIO
// quadrature encoders ([[gpiod_encoder]]), Modbus controllers and their registers
// ([[modbus_device]]), and the acquisition daemon's settings ([daemon]). The loader
// (bench_config.cpp) calls these readers (bench_config_readers.hpp) for its top-level tables.
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/config/bench_config_readers.hpp"
#include "common/config/machine_safety.hpp"
#include "common/config/register_role.hpp"
#include "common/config/toml_reader.hpp"

namespace inertia::config {

namespace detail {

namespace {

DeviceAvailability read_availability(const TableReader& t) {
  return DeviceAvailability{t.boolean_or("optional", false), t.where(), t.number_in("silent_timeout_s", 1.0, 1e-3, 3600.0),
                            t.integer_in("latency_floor_ns", 0, 0, 1'000'000'000)};
}

// Plausible range (`min`, `max`) and stuck watch (`stuck_after_s`) of a reading.
void read_plausible(const TableReader& t, double& min, double& max, double& stuck_after_s) {
  if (t.has("min")) min = t.number("min");
  if (t.has("max")) max = t.number("max");
  if (!(min < max)) t.fail_key("max", "must be greater than min");
  stuck_after_s = t.number_in("stuck_after_s", 0.0, 0.0, 3600.0);
}

int register_words(RegisterType type) { return type == RegisterType::U16 || type == RegisterType::I16 ? 1 : 2; }

// Two registers of one kind sharing an address would be two readings of the same words: a typo
// in an address, or a 32-bit value whose second word was forgotten.
void fail_on_overlap(const TableReader& r, const ModbusRegister& reg, const std::vector<ModbusRegister>& before) {
  const int end = reg.address + register_words(reg.type);
  for (const ModbusRegister& other : before) {
    const int other_end = other.address + register_words(other.type);
    if (other.kind != reg.kind || end <= other.address || other_end <= reg.address) continue;
    auto words = [](int from, int to) {
      return to - from == 1 ? "address " + std::to_string(from)
                            : "addresses " + std::to_string(from) + ".." + std::to_string(to - 1);
    };
    r.fail_key("address", "register '" + reg.name + "' (" + words(reg.address, end) + ") overlaps register '" +
                              other.name + "' (" + words(other.address, other_end) + ", line " +
                              std::to_string(other.where.line) + ") in the " +
                              (reg.kind == RegisterKind::Input ? "input" : "holding") + " registers");
  }
}

}  // namespace

CanDevice read_can_device(const TableReader& t) {
  CanDevice d;
  d.name = t.string("name");
  d.interface = t.string_or("interface", d.interface);
  d.interface_at = t.where("interface");
  d.availability = read_availability(t);
  d.sample_rate_hz = t.number_in("sample_rate_hz", 0.0, 0.0, 1e6);
  d.fd = t.boolean_or("fd", false);
  // ISO 11898: up to 1 Mbit/s in the arbitration phase; CAN FD data phases reach 8-12 Mbit/s.
  d.bitrate = static_cast<std::uint32_t>(t.integer_in("bitrate", 0, 0, 1'000'000));
  d.dbitrate = static_cast<std::uint32_t>(t.integer_in("dbitrate", 0, 0, 15'000'000));
  if (d.dbitrate != 0 && !d.fd) t.fail_key("dbitrate", "a data-phase bit rate needs fd = true (CAN FD)");
  const unsigned payload_bytes = d.fd ? 64 : 8;
  for (const TableReader& s : t.tables("signal")) {
    CanSignal c;
    c.name = s.string("name");
    c.extended = s.boolean_or("extended", false);
    c.id = static_cast<std::uint32_t>(s.integer_in("id", -1, 0, c.extended ? 0x1FFFFFFF : 0x7FF));
    c.byte_offset = static_cast<unsigned>(s.integer_in("byte_offset", 0, 0, 63));
    c.bit_offset = static_cast<unsigned>(s.integer_in("bit_offset", 0, 0, 7));
    c.bit_length = static_cast<unsigned>(s.integer_in("bit_length", 16, 1, 64));
    if (c.byte_offset * 8 + c.bit_offset + c.bit_length > payload_bytes * 8) {
      s.fail_key("bit_length", "the signal (bits " + std::to_string(c.byte_offset * 8 + c.bit_offset) + ".." +
                                   std::to_string(c.byte_offset * 8 + c.bit_offset + c.bit_length - 1) +
                                   ") runs past the " + std::to_string(payload_bytes) + "-byte payload of " +
                                   (d.fd ? "a CAN FD frame" : "a classic CAN frame (fd = true on the device for CAN FD)"));
    }
    c.byte_order = s.choice_or("byte_order", {"little", "big"}, 0) == 0 ? ByteOrder::LittleEndian
                                                                         : ByteOrder::BigEndian;
    c.is_signed = s.boolean_or("signed", false);
    c.scale = s.number_or("scale", 1.0);
    if (c.scale == 0.0) s.fail_key("scale", "must not be 0");
    c.offset = s.number_or("offset", 0.0);
    c.unit = s.string_or("unit", "");
    c.counter = s.boolean_or("counter", false);
    if (c.counter && c.is_signed) s.fail_key("counter", "a frame counter is unsigned (signed = false)");
    c.wraps = s.boolean_or("wraps", false);
    if (c.wraps && c.counter)
      s.fail_key("wraps", "a frame counter is unwrapped as the frame's number; wraps is for an accumulating count");
    read_plausible(s, c.min, c.max, c.stuck_after_s);
    if (c.counter && (s.has("min") || s.has("max") || c.stuck_after_s > 0.0))
      s.fail_key(s.has("min") ? "min" : s.has("max") ? "max" : "stuck_after_s", "a frame counter is no reading");
    if (s.has("invalid_raw")) {
      // TOML integers are 64-bit signed: a 64-bit code above INT64_MAX is written negative.
      const bool all64 = c.bit_length == 64;
      const std::int64_t hi = all64 ? std::numeric_limits<std::int64_t>::max()
                                    : static_cast<std::int64_t>((std::uint64_t{1} << c.bit_length) - 1);
      const std::int64_t lo = all64 ? std::numeric_limits<std::int64_t>::min()
                              : c.is_signed ? -static_cast<std::int64_t>(std::uint64_t{1} << (c.bit_length - 1))
                                            : 0;
      const std::int64_t v = s.integer_in("invalid_raw", 0, lo, hi);
      const std::uint64_t mask = all64 ? ~std::uint64_t{0} : (std::uint64_t{1} << c.bit_length) - 1;
      c.invalid_raw = static_cast<std::uint64_t>(v) & mask;  // two's complement bits of a negative code
    }
    s.finish();
    d.signals.push_back(std::move(c));
  }
  if (d.signals.empty()) t.fail_here("a CAN device needs at least one [[can_device.signal]]");
  t.finish();
  return d;
}

GpiodEncoder read_gpiod_encoder(const TableReader& t) {
  GpiodEncoder e;
  e.name = t.string("name");
  e.chip = t.string_or("chip", e.chip);
  e.chip_at = t.where("chip");
  e.availability = read_availability(t);
  const char* line_keys[4] = {"line_a", "line_b", "line_marker", "line_trigger"};
  for (int i = 0; i < 4; ++i) e.line_at[i] = t.where(line_keys[i]);
  e.line_a = static_cast<int>(t.integer_in("line_a", -1, 0, 1023));
  e.line_b = static_cast<int>(t.integer_in("line_b", -1, 0, 1023));
  if (e.line_a == e.line_b) t.fail_key("line_b", "must differ from line_a");
  e.line_marker = static_cast<int>(t.integer_in("line_marker", -1, -1, 1023));
  e.line_trigger = static_cast<int>(t.integer_in("line_trigger", -1, -1, 1023));
  e.active_low = t.boolean_or("active_low", false);
  e.rotary = t.choice("kind", {"linear", "rotary"}) == 1;
  e.resolution = t.positive("resolution");
  e.edge_latency_ns = t.integer_in("edge_latency_ns", e.edge_latency_ns, 0, 1'000'000'000);
  t.finish();
  return e;
}

DaemonSettings read_daemon(const TableReader& t) {
  DaemonSettings d;
  if (t.has("log_dir")) {
    d.log_dir = t.string("log_dir");
    if (d.log_dir->empty()) t.fail_key("log_dir", "must not be empty (leave the key out for no log)");
  }
  if (t.has("lcm_url")) d.lcm_url = t.string("lcm_url");
  for (auto [key, target] : {std::pair{"state_dir", &d.state_dir}, std::pair{"command_socket", &d.command_socket},
                              std::pair{"command_key", &d.command_key}, std::pair{"operator_group", &d.operator_group}}) {
    if (!t.has(key)) continue;
    *target = t.string(key);
    if (target->value().empty()) t.fail_key(key, "must not be empty (leave the key out for the default)");
  }
  if (t.has("block_ms")) {
    d.block_ms = t.positive("block_ms");
    if (*d.block_ms > DaemonLimits::kMaxBlockMs) t.fail_key("block_ms", "must be at most " + std::to_string(static_cast<int>(DaemonLimits::kMaxBlockMs)) + " ms");
  }
  if (t.has("rotate_mb")) d.rotate_mb = t.positive("rotate_mb");
  if (t.has("fsync_ms")) d.fsync_ms = static_cast<int>(t.integer_in("fsync_ms", 1000, 1, DaemonLimits::kMaxFsyncMs));
  if (t.has("log_queue")) d.log_queue = static_cast<int>(t.integer_in("log_queue", 512, 4, DaemonLimits::kMaxLogQueue));
  if (t.has("ring_samples"))
    d.ring_samples = static_cast<int>(t.integer_in("ring_samples", 1 << 17, 1024, DaemonLimits::kMaxRingSamples));
  if (t.has("fifo_priority")) d.fifo_priority = static_cast<int>(t.integer_in("fifo_priority", 0, 0, DaemonLimits::kMaxFifoPriority));
  if (t.has("cpu_affinity")) d.cpu_affinity = static_cast<int>(t.integer_in("cpu_affinity", -1, -1, DaemonLimits::kMaxCpu));
  if (t.has("mlock")) d.mlock = t.boolean_or("mlock", false);
  t.finish();
  return d;
}

ModbusDevice read_modbus_device(const TableReader& t) {
  ModbusDevice d;
  d.name = t.string("name");
  d.role = static_cast<ControllerRole>(t.choice("role", {"thermal", "table", "shaker"}));
  d.availability = read_availability(t);
  d.transport = t.choice_or("transport", {"tcp", "rtu"}, 0) == 0 ? ModbusTransport::Tcp : ModbusTransport::Rtu;
  if (d.transport == ModbusTransport::Tcp) {
    for (const char* serial_key : {"serial_port", "baud", "parity", "data_bits", "stop_bits"})
      if (t.has(serial_key)) t.fail_key(serial_key, "is a serial-line setting; it needs transport = \"rtu\"");
    d.host = t.string_or("host", d.host);
    d.endpoint_at = t.where("host");
    d.port = static_cast<int>(t.integer_in("port", d.port, 1, 65535));
  } else {
    for (const char* tcp_key : {"host", "port"})
      if (t.has(tcp_key)) t.fail_key(tcp_key, "is a TCP setting; a transport = \"rtu\" device has serial_port instead");
    d.serial_port = t.string("serial_port");
    if (d.serial_port.empty()) t.fail_key("serial_port", "must name the serial device, e.g. /dev/ttyUSB0");
    d.endpoint_at = t.where("serial_port");
    d.baud = static_cast<int>(t.integer_in("baud", d.baud, 50, 4'000'000));
    d.parity = static_cast<SerialParity>(t.choice_or("parity", {"none", "even", "odd"}, 1));
    d.data_bits = static_cast<int>(t.integer_in("data_bits", d.data_bits, 5, 8));
    d.stop_bits = static_cast<int>(t.integer_in("stop_bits", d.stop_bits, 1, 2));
  }
  // On a serial line the unit id is the slave address: 1..247 (0 is broadcast, never answered).
  d.unit_id = d.transport == ModbusTransport::Tcp ? static_cast<int>(t.integer_in("unit_id", d.unit_id, 0, 255))
                                                  : static_cast<int>(t.integer_in("unit_id", d.unit_id, 1, 247));
  d.poll_interval_ms = static_cast<int>(t.integer_in("poll_interval_ms", d.poll_interval_ms, 1, 60000));
  d.response_timeout_s = t.positive_or("response_timeout_s", d.response_timeout_s);
  d.reconnect_initial_s = t.positive_or("reconnect_initial_s", d.reconnect_initial_s);
  d.reconnect_max_s = t.positive_or("reconnect_max_s", d.reconnect_max_s);
  d.timeouts_before_reconnect =
      static_cast<int>(t.integer_in("timeouts_before_reconnect", d.timeouts_before_reconnect, 1, 1000));
  d.writes_enabled = t.boolean_or("writes_enabled", false);
  std::set<std::string> names;
  const std::vector<TableReader> registers = t.tables("register");
  for (const TableReader& r : registers) {
    ModbusRegister reg;
    reg.where = r.where();
    reg.name = r.string("name");
    reg.address = static_cast<int>(r.integer_in("address", -1, 0, 65535));
    reg.kind = r.choice_or("kind", {"holding", "input"}, 0) == 0 ? RegisterKind::Holding : RegisterKind::Input;
    reg.type = static_cast<RegisterType>(r.choice_or("type", {"u16", "i16", "u32", "i32", "f32"}, 0));
    reg.order = static_cast<WordOrder>(r.choice_or("word_order", {"ABCD", "CDAB", "BADC", "DCBA"}, 0));
    reg.scale = r.number_or("scale", 1.0);
    if (reg.scale == 0.0) r.fail_key("scale", "must not be 0");
    reg.offset = r.number_or("offset", 0.0);
    reg.unit = r.string_or("unit", "");
    reg.writable = r.boolean_or("writable", false);
    if (reg.writable) {
      if (reg.kind == RegisterKind::Input) r.fail_key("writable", "an input register cannot be written");
      // A setpoint without limits is refused: every write is clamped to [min, max].
      reg.min = r.number("min");
      reg.max = r.number("max");
      if (!(reg.min < reg.max)) r.fail_key("max", "must be greater than min");
    } else if (r.has("min") || r.has("max")) {
      r.fail_key(r.has("min") ? "min" : "max", "limits apply to writable registers only (a reading's plausible range is `range`)");
    }
    if (r.has("range")) {
      const std::vector<double> range = r.numbers("range");
      if (range.size() != 2 || !(range[0] < range[1])) r.fail_key("range", "must be [lo, hi] with lo < hi");
      reg.range_min = range[0];
      reg.range_max = range[1];
    }
    reg.stuck_after_s = r.number_in("stuck_after_s", 0.0, 0.0, 3600.0);
    read_register_role(r, reg);
    r.finish();
    if (!names.insert(reg.name).second) r.fail_key("name", "duplicate register name '" + reg.name + "'");
    fail_on_overlap(r, reg, d.registers);
    d.registers.push_back(std::move(reg));
  }
  check_register_references(registers, d);
  check_machine_safety(t, registers, d);
  t.finish();
  return d;
}

// Modbus RTU has one master per RS-485 line, and every [[modbus_device]] is a master of its own
// (its own poller): two of them on one port would talk over each other.
void check_one_master_per_serial_line(const std::vector<ModbusDevice>& devices) {
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const ModbusDevice& d = devices[i];
    if (d.transport != ModbusTransport::Rtu) continue;
    for (std::size_t j = 0; j < i; ++j) {
      const ModbusDevice& e = devices[j];
      if (e.transport != ModbusTransport::Rtu) continue;
      std::error_code ec;   // two names of one adapter (a /dev/serial/by-id link) are one port where both exist
      if (e.serial_port != d.serial_port && !std::filesystem::equivalent(e.serial_port, d.serial_port, ec)) continue;
      throw InputError(d.endpoint_at, "serial port '" + d.serial_port + "' is already the line of [[modbus_device]] '" +
                                          e.name + "' (line " + std::to_string(e.endpoint_at.line) +
                                          "): Modbus RTU has one master per RS-485 line and each [[modbus_device]] is one. "
                                          "Wire this controller (unit_id " + std::to_string(d.unit_id) +
                                          ") to a second adapter and name that serial_port here");
    }
  }
}

}  // namespace detail

const char* to_string(RegisterRole role) {
  switch (role) {
    case RegisterRole::None: return "none";
    case RegisterRole::TableRate: return "table_rate";
    case RegisterRole::TableAngle: return "table_angle";
    case RegisterRole::ShakerRun: return "shaker_run";
    case RegisterRole::ShakerProfile: return "shaker_profile";
    case RegisterRole::ThermalSetpoint: return "thermal_setpoint";
    case RegisterRole::Fault: return "fault";
    case RegisterRole::Heartbeat: return "heartbeat";
  }
  return "?";
}

}  // namespace inertia::config
