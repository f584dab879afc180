#include "common/config/bench_config.hpp"

#include <numbers>

#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <sstream>
#include <utility>

#include "common/config/controller_plan.hpp"
#include "common/config/link_capacity.hpp"
#include "common/config/machine_safety.hpp"
#include "common/config/register_role.hpp"
#include "common/config/toml_reader.hpp"
#include "common/units.hpp"

namespace inertia::config {

namespace {

constexpr double kDefaultAlphaDeg = 25.0;   // the paper's suggestion for Fig. 2 (section 2.3)

AxisAngle read_axis_angle(const TableReader& parent, std::string_view key) {
  AxisAngle out;
  const auto t = parent.optional_table(key);
  if (!t) return out;
  out.axis = t->nonzero_vec3("axis");
  out.angle_rad = deg_to_rad(t->number("angle_deg"));
  t->finish();
  return out;
}

std::uint64_t read_seed(const TableReader& t, std::string_view key, std::uint64_t fallback) {
  return static_cast<std::uint64_t>(
      t.integer_in(key, static_cast<std::int64_t>(fallback), 0, std::numeric_limits<std::int64_t>::max()));
}

void read_thermal(const TableReader& t, ThermalController& th) {
  th.ambient_c = t.number_in("ambient_c", th.ambient_c, -100.0, 200.0);
  th.initial_c = t.number_in("initial_c", th.initial_c, -100.0, 200.0);
  th.tau_s = t.positive_or("tau_s", th.tau_s);
  th.heat_rate_max_c_per_s = t.positive_or("heat_rate_max_c_per_s", th.heat_rate_max_c_per_s);
  th.kp_per_c = t.number_in("kp_per_c", th.kp_per_c, 0.0, 1e6);
  th.ki_per_c_s = t.number_in("ki_per_c_s", th.ki_per_c_s, 0.0, 1e6);
  th.sensor_noise_sd_c = t.number_in("sensor_noise_sd_c", th.sensor_noise_sd_c, 0.0, 100.0);
  th.channel = t.string_or("channel", "");
  t.finish();
}

MonitorAccelerometer read_monitor(const TableReader& t, bool named) {
  MonitorAccelerometer m;
  m.name = named ? t.string("name") : t.string_or("name", "control");
  if (m.name.empty() || m.name.find_first_of(",\" \t") != std::string::npos) {
    t.fail_key("name", "must be a non-empty name without commas, quotes or spaces (it heads a CSV column)");
  }
  m.axis = t.has("axis") ? t.nonzero_vec3("axis").normalized() : Eigen::Vector3d::UnitX();
  m.bias_mps2 = g_to_mps2(t.number_or("bias_g", 0.0));
  m.scale_error = t.number_in("scale_error", 0.0, -0.5, 0.5);
  m.misalignment = read_axis_angle(t, "misalignment");
  m.noise_sd_mps2 = g_to_mps2(t.number_in("noise_sd_g", 0.0, 0.0, 1e3));
  m.channel = t.string_or("channel", "");
  t.finish();
  return m;
}

Encoder read_encoder(const TableReader& t, std::string_view resolution_key, bool simulated) {
  Encoder e;
  e.present = true;
  e.resolution = t.positive(resolution_key);
  e.channel = t.string_or("channel", "");
  if (t.has("wire") && !simulated)
    t.fail_key("wire", "is for simulated benches: a real bench's encoder is wired by its [[gpiod_encoder]] or "
                       "[[can_device]], named in `channel`");
  e.wire = t.choice_or("wire", {"gpio", "can"}, 0) == 0 ? EncoderWire::Gpio : EncoderWire::Can;
  t.finish();
  return e;
}

std::vector<TruthValue> read_truth(const TableReader& t) {
  std::vector<TruthValue> out;
  for (const auto& [key, node] : t.entries()) {
    TruthValue v;
    v.name = key;
    v.where = position_of(*node, t.file());
    if (const toml::array* a = node->as_array()) {
      v.is_array = true;
      for (const toml::node& e : *a) {
        const auto d = e.value<double>();
        if (!d) t.fail(e, t.key_name(key) + " must hold numbers only");
        v.values.push_back(*d);
      }
    } else if (const auto d = node->value<double>(); d && !node->is_boolean()) {
      v.values.push_back(*d);
    } else {
      t.fail(*node, t.key_name(key) + " must be a number or an array of numbers");
    }
    out.push_back(std::move(v));
  }
  return out;
}

SensorUnderTest read_sensor(const TableReader& t, std::size_t index, std::uint64_t bench_seed) {
  SensorUnderTest s;
  s.where = t.where();
  s.name = t.string("name");
  if (s.name.empty() || s.name.find_first_of("/\\ ") != std::string::npos) {
    t.fail_key("name", "must be a non-empty name without '/', '\\' or spaces (it names a folder)");
  }
  s.type = t.choice("type", {"accelerometer", "gyroscope"}) == 0 ? SensorType::Accelerometer
                                                                   : SensorType::Gyroscope;
  s.output_unit = t.string_or("output_unit", s.output_unit);
  s.slot = t.string_or("slot", "");
  s.position_m = t.vec3_or("position_m", Eigen::Vector3d::Zero());
  s.seed = read_seed(t, "seed", derived_sensor_seed(bench_seed, index));
  s.channel = t.string_or("channel", "");
  s.case_misalignment = read_axis_angle(t, "case_misalignment");
  if (const auto truth = t.optional_table("truth")) s.truth = read_truth(*truth);
  t.finish();
  return s;
}

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

// Which phases make physical sense on which facility.
bool phase_allowed(CaseKind c, PhaseKind p) {
  if (p == PhaseKind::Dwell || p == PhaseKind::ThermalStep) return true;
  switch (c) {
    case CaseKind::RotationTable: return p == PhaseKind::Rotation;
    case CaseKind::Shaker: return p == PhaseKind::Sine || p == PhaseKind::Random || p == PhaseKind::Shock;
    case CaseKind::Thermal:
    case CaseKind::Static: return false;
  }
  return false;
}

Phase read_phase(const TableReader& t, CaseKind case_kind, double sample_rate_hz) {
  Phase p;
  p.where = t.where();
  p.command_at = p.where;
  p.kind = static_cast<PhaseKind>(
      t.choice("kind", {"dwell", "rotation", "sine", "random", "shock", "thermal_step"}));
  if (!phase_allowed(case_kind, p.kind)) {
    t.fail_key("kind", std::string("a ") + to_string(p.kind) + " phase cannot run in a " +
                           to_string(case_kind) + " case");
  }
  p.duration_s = t.positive("duration_s");
  if (p.duration_s * sample_rate_hz < 1.0) t.fail_key("duration_s", "is shorter than one sample period");
  const double nyquist = sample_rate_hz / 2.0;
  switch (p.kind) {
    case PhaseKind::Dwell: break;
    case PhaseKind::Rotation:
      p.axis = t.nonzero_vec3("axis").normalized();
      if (t.has("rate_deg_s") == t.has("angle_deg")) {
        t.fail_here("a rotation needs exactly one of rate_deg_s or angle_deg");
      }
      if (t.has("rate_deg_s")) p.rate_rad_s = deg_to_rad(t.number("rate_deg_s"));
      if (t.has("angle_deg")) p.angle_rad = deg_to_rad(t.number("angle_deg"));
      p.command_at = t.where(t.has("rate_deg_s") ? "rate_deg_s" : "angle_deg");
      break;
    case PhaseKind::Sine:
      p.frequency_hz = t.positive("frequency_hz");
      if (p.frequency_hz >= nyquist) t.fail_key("frequency_hz", "must be below the Nyquist frequency");
      p.amplitude_mps2 = g_to_mps2(t.positive("amplitude_g"));
      p.ramp_cycles = t.number_in("ramp_cycles", p.ramp_cycles, 0.0, 1e6);
      if (2.0 * p.ramp_cycles / p.frequency_hz > p.duration_s) {
        t.fail_key("ramp_cycles", "the two ramps are longer than duration_s");
      }
      break;
    case PhaseKind::Random:
      p.f1_hz = t.positive("f1_hz");
      p.f2_hz = t.positive("f2_hz");
      if (!(p.f1_hz < p.f2_hz)) t.fail_key("f2_hz", "must be greater than f1_hz");
      if (p.f2_hz >= nyquist) t.fail_key("f2_hz", "must be below the Nyquist frequency");
      p.rms_mps2 = g_to_mps2(t.positive("grms"));
      p.ramp_s = t.number_in("ramp_s", p.ramp_s, 0.0, 1e6);
      if (2.0 * p.ramp_s >= p.duration_s) t.fail_key("ramp_s", "the two tapers are longer than duration_s");
      if (p.f1_hz * p.duration_s < 2.0) {
        t.fail_key("f1_hz", "the phase must span at least two periods of f1_hz");
      }
      // The synthesis puts equal amplitudes on the FFT bins of the band (spacing <= 1/duration).
      if ((p.f2_hz - p.f1_hz) * p.duration_s < 4.0) {
        t.fail_key("f2_hz", "the band f1_hz..f2_hz must hold at least 4 frequency bins (width >= 4/duration_s)");
      }
      break;
    case PhaseKind::Shock:
      p.peak_mps2 = g_to_mps2(t.number("peak_g"));
      if (p.peak_mps2 == 0.0) t.fail_key("peak_g", "must not be 0");
      p.pulse_s = t.positive("pulse_s");
      p.compensation = t.number_in("compensation", p.compensation, 1.0, 1e3);
      if (p.pulse_s * (1.0 + 2.0 * p.compensation) > p.duration_s) {
        t.fail_key("pulse_s", "pulse plus compensating pulses (pulse_s*(1 + 2*compensation)) exceed duration_s");
      }
      if (p.pulse_s * sample_rate_hz < 4.0) t.fail_key("pulse_s", "needs at least 4 samples");
      break;
    case PhaseKind::ThermalStep:
      if (!t.has("setpoint_c")) t.fail_here("missing key 'setpoint_c' (expected a number)");
      p.setpoint_c = t.number_in("setpoint_c", 0.0, -100.0, 200.0);
      p.command_at = t.where("setpoint_c");
      break;
  }
  if (p.kind == PhaseKind::Sine || p.kind == PhaseKind::Random || p.kind == PhaseKind::Shock) {
    if (t.has("profile")) {
      p.profile = static_cast<int>(t.integer_in("profile", 0, 0, 65535));
      p.command_at = t.where("profile");
    }
  }
  t.finish();
  return p;
}

TestCase read_case(const TableReader& t, double alpha_rad, double sample_rate_hz) {
  TestCase c;
  c.where = t.where();
  c.name = t.string("name");
  if (c.name.empty() || c.name.find_first_of("/\\ ") != std::string::npos) {
    t.fail_key("name", "must be a non-empty name without '/', '\\' or spaces (it names a file)");
  }
  c.kind = static_cast<CaseKind>(t.choice("kind", {"rotation_table", "shaker", "thermal", "static"}));
  if (t.has("orientation") == t.has("m_ec")) {
    t.fail_here("a case needs exactly one of orientation (\"IA\", \"PA\", \"OA\": Fig. 2 slot) or m_ec");
  }
  if (t.has("orientation")) {
    c.orientation = static_cast<Orientation>(t.choice("orientation", {"IA", "PA", "OA"}));
    c.m_ec = slot_orientation(*c.orientation, alpha_rad);
  } else {
    c.m_ec = t.mat3("m_ec");
    if (!frames::is_rotation(c.m_ec, 1e-6)) t.fail_key("m_ec", "must be a rotation (orthonormal, det +1)");
  }
  c.mounting = t.string_or("mounting", "");
  c.fixture_misalignment = read_axis_angle(t, "fixture_misalignment");
  c.case_misalignment = read_axis_angle(t, "case_misalignment");
  c.start_attitude = read_axis_angle(t, "start_attitude");
  if (t.has("placement_error_deg")) {
    const double deg = t.number("placement_error_deg");
    if (!(deg >= 0.0 && deg <= 10.0)) t.fail_key("placement_error_deg", "must be within 0..10 degrees");
    c.placement_error_rad = deg * std::numbers::pi / 180.0;
  }
  if (c.kind != CaseKind::RotationTable && t.has("start_attitude")) {
    t.fail_key("start_attitude", "only a rotation_table case has a table attitude");
  }
  for (const TableReader& p : t.tables("phase")) c.phases.push_back(read_phase(p, c.kind, sample_rate_hz));
  if (c.phases.empty()) t.fail_here("a case needs at least one [[case.phase]]");
  t.finish();
  return c;
}

std::optional<std::string> read_text_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  return std::move(text).str();
}

// Where the loader gets a file's text: the disk, or the texts carried by INERTIA_BENCH.
// nullopt when the file does not exist there.
using SourceFetch = std::function<std::optional<std::string>(const std::filesystem::path&)>;

void read_cases(const TableReader& root, BenchConfig& cfg, std::set<std::string>& names, int depth,
                const SourceFetch& fetch) {
  for (const TableReader& c : root.tables("case")) {
    TestCase tc = read_case(c, cfg.alpha_rad, cfg.sample_rate_hz);
    if (!names.insert(tc.name).second) c.fail_key("name", "duplicate case name '" + tc.name + "'");
    cfg.cases.push_back(std::move(tc));
  }
  if (!root.has("include")) return;
  const toml::node* inc = root.node("include");
  const toml::array* list = inc->as_array();
  if (list == nullptr) root.fail(*inc, "include must be an array of file names");
  if (depth > 4) root.fail(*inc, "include nested too deeply (a cycle?)");
  const std::filesystem::path base = std::filesystem::path(root.file()).parent_path();
  for (const toml::node& e : *list) {
    const auto name = e.value_exact<std::string>();
    if (!name) root.fail(e, "include must list file names (strings)");
    const std::filesystem::path path = base / *name;
    std::optional<std::string> text = fetch(path);
    if (!text) root.fail(e, "included file '" + path.string() + "' not found");
    const toml::table sub = parse_toml_text(*text, path.string());
    cfg.sources.push_back({path, std::move(*text)});
    // An included file holds a test plan only: [[case]] tables and further includes.
    const TableReader reader(sub, "", path.string());
    read_cases(reader, cfg, names, depth + 1, fetch);
    reader.finish();
  }
}

BenchConfig load_bench(const std::filesystem::path& path, std::string text, const SourceFetch& fetch) {
  const toml::table root_table = parse_toml_text(text, path.string());
  const TableReader root(root_table, "", path.string());
  BenchConfig cfg;
  cfg.file = path;
  cfg.sources.push_back({path, std::move(text)});

  const TableReader bench = root.table("bench");
  cfg.name = bench.string("name");
  cfg.simulated = bench.choice_or("backend", {"sim", "real"}, 0) == 0;
  cfg.executive_at = bench.where("executive");
  if (bench.has("executive")) {
    if (cfg.simulated) bench.fail_key("executive", "is for real benches: a simulated bench runs its plan in the simulator");
    cfg.executive = bench.choice("executive", {"operator", "plan"}) == 0 ? Executive::Operator : Executive::Plan;
  }
  if (bench.has("stop_within_s")) {
    if (cfg.simulated) bench.fail_key("stop_within_s", "is for real benches: a simulated bench commands no machinery");
    cfg.stop_within_s = bench.positive("stop_within_s");
    cfg.stop_within_at = bench.where("stop_within_s");
  }
  cfg.sample_rate_hz = bench.positive("sample_rate_hz");
  cfg.t_ref_c = bench.number_in("t_ref_c", cfg.t_ref_c, -100.0, 200.0);
  cfg.seed = read_seed(bench, "seed", cfg.seed);
  if (const auto timing = bench.optional_table("sim_timing")) {
    cfg.sim_timing.enabled = true;
    cfg.sim_timing.jitter_s = 1e-6 * timing->number_in("jitter_us", 0.0, 0.0, 1e5);
    cfg.sim_timing.clock_ppm = timing->number_in("clock_ppm", 0.0, -1000.0, 1000.0);
    cfg.sim_timing.frame_loss = timing->number_in("frame_loss", 0.0, 0.0, 0.5);
    // From a byte's counter up; a 16-bit one at 10 kHz rolls over every 6.6 s.
    cfg.sim_timing.counter_bits = static_cast<int>(timing->integer_in("counter_bits", 32, 8, 32));
    timing->finish();
  }
  bench.finish();

  cfg.alpha_rad = deg_to_rad(kDefaultAlphaDeg);
  if (const auto fixture = root.optional_table("fixture")) {
    const double alpha_deg = fixture->number_in("alpha_deg", kDefaultAlphaDeg, 0.0, 90.0);
    if (alpha_deg == 0.0 || alpha_deg == 90.0) {
      fixture->fail_key("alpha_deg", "must be strictly between 0 and 90 (section 2.3: alpha != 0)");
    }
    cfg.alpha_rad = deg_to_rad(alpha_deg);
    if (const auto th = fixture->optional_table("thermal")) read_thermal(*th, cfg.thermal);
    fixture->finish();
  }

  std::set<std::string> names;
  const std::vector<TableReader> sensors = root.tables("sensor");
  for (std::size_t i = 0; i < sensors.size(); ++i) {
    cfg.sensors.push_back(read_sensor(sensors[i], i, cfg.seed));
    if (!names.insert(cfg.sensors.back().name).second) {
      sensors[i].fail_key("name", "duplicate sensor name '" + cfg.sensors.back().name + "'");
    }
  }
  if (cfg.simulated && cfg.sensors.empty()) root.fail_here("a simulated bench needs at least one [[sensor]]");

  std::set<std::string> monitor_names;
  for (const TableReader& m : root.tables("monitor")) {
    cfg.monitors.push_back(read_monitor(m, true));
    if (!monitor_names.insert(cfg.monitors.back().name).second) {
      m.fail_key("name", "duplicate monitor name '" + cfg.monitors.back().name + "'");
    }
  }
  if (const auto c = root.optional_table("control_accelerometer")) cfg.control_accelerometer = read_monitor(*c, false);
  if (const auto e = root.optional_table("linear_encoder")) cfg.linear_encoder = read_encoder(*e, "resolution_m", cfg.simulated);
  if (const auto e = root.optional_table("table_encoder")) cfg.table_encoder = read_encoder(*e, "resolution_rad", cfg.simulated);

  for (const TableReader& d : root.tables("can_device")) cfg.can_devices.push_back(read_can_device(d));
  for (const TableReader& d : root.tables("gpiod_encoder")) cfg.gpiod_encoders.push_back(read_gpiod_encoder(d));
  for (const TableReader& d : root.tables("modbus_device")) cfg.modbus_devices.push_back(read_modbus_device(d));
  check_one_master_per_serial_line(cfg.modbus_devices);
  if (const auto d = root.optional_table("daemon")) cfg.daemon = read_daemon(*d);

  std::set<std::string> case_names;
  read_cases(root, cfg, case_names, 0, fetch);
  if (cfg.simulated && cfg.cases.empty()) root.fail_here("a simulated bench needs a test plan ([[case]] tables)");
  root.finish();
  check_plan_against_controllers(cfg);
  if (!cfg.simulated) check_link_capacity(cfg);
  return cfg;
}

}  // namespace

frames::Dcm slot_orientation(Orientation orientation, double alpha_rad) {
  const double c = std::cos(alpha_rad), s = std::sin(alpha_rad);
  const int k = static_cast<int>(orientation);
  frames::Dcm m;
  m.row(k) << c, s, 0.0;
  m.row((k + 1) % 3) << 0.0, 0.0, 1.0;
  m.row((k + 2) % 3) << s, -c, 0.0;   // = row k x row k+1: right-handed (det +1)
  return m;
}

std::uint64_t derived_sensor_seed(std::uint64_t bench_seed, std::size_t index) {
  return bench_seed * 1000003u + 17u * (index + 1);
}

void reseed(BenchConfig& bench, std::uint64_t seed) {
  bench.seed = seed;
  for (std::size_t i = 0; i < bench.sensors.size(); ++i) bench.sensors[i].seed = derived_sensor_seed(seed, i);
}

BenchConfig load_bench_config(const std::filesystem::path& path) {
  std::optional<std::string> text = read_text_file(path);
  if (!text) throw InputError(SourcePosition{path.string(), 0, 0}, "file not found");
  return load_bench(path, std::move(*text), read_text_file);
}

BenchConfig load_bench_config_from_sources(const std::vector<SourceFile>& sources) {
  if (sources.empty()) throw InputError("bench config: no files (the bench file's text is missing)");
  const SourceFetch fetch = [&sources](const std::filesystem::path& path) -> std::optional<std::string> {
    for (const SourceFile& f : sources)
      if (f.path.lexically_normal() == path.lexically_normal()) return f.text;
    return std::nullopt;
  };
  return load_bench(sources.front().path, sources.front().text, fetch);
}

const char* to_string(PhaseKind kind) {
  switch (kind) {
    case PhaseKind::Dwell: return "dwell";
    case PhaseKind::Rotation: return "rotation";
    case PhaseKind::Sine: return "sine";
    case PhaseKind::Random: return "random";
    case PhaseKind::Shock: return "shock";
    case PhaseKind::ThermalStep: return "thermal_step";
  }
  return "?";
}

const char* to_string(SensorType type) {
  return type == SensorType::Accelerometer ? "accelerometer" : "gyroscope";
}

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

const char* to_string(Orientation orientation) {
  switch (orientation) {
    case Orientation::IA: return "IA";
    case Orientation::PA: return "PA";
    case Orientation::OA: return "OA";
  }
  return "?";
}

}  // namespace inertia::config
