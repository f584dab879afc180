#include "daq/device_check.hpp"

#include <linux/can.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <ostream>
#include <span>
#include <sstream>

#include "common/config/machine_safety.hpp"
#include "daq/real_bench.hpp"
#include "hal/gpiod/line_probe.hpp"
#include "hal/modbus/modbus_controller.hpp"
#include "hal/socketcan/can_device.hpp"
#include "hal/socketcan/can_interface.hpp"
#include "hal/unique_fd.hpp"

namespace inertia::daq {
namespace {

constexpr const char* kConsumer = "inertia-daqd --check";

std::string bits_per_second(std::uint32_t b) {
  std::ostringstream s;
  if (b % 1'000'000 == 0) s << b / 1'000'000 << " Mbit/s";
  else if (b % 1000 == 0) s << b / 1000 << " kbit/s";
  else s << b << " bit/s";
  return s.str();
}

std::string number(double v) {
  std::ostringstream s;
  s << std::setprecision(6) << v;
  return s.str();
}

/// Rows of one device share its name, kind and optional flag.
struct RowMaker {
  std::string device, kind;
  bool optional;
  std::vector<CheckRow> rows;
  CheckRow& add(std::string item, CheckStatus status, std::string detail, const SourcePosition& where,
                std::string fix = {}) {
    rows.push_back(CheckRow{device, kind, std::move(item), status, std::move(detail), std::move(fix), where, optional});
    return rows.back();
  }
};

// ---- CAN ----------------------------------------------------------------------------------

/// The command that brings a controller up as the bench wants it.
std::string can_up_command(const config::CanDevice& d) {
  std::string cmd = "ip link set " + d.interface + " up type can bitrate " +
                    (d.bitrate != 0 ? std::to_string(d.bitrate) : std::string("<the bus's bit rate>"));
  if (d.fd) cmd += " dbitrate " + (d.dbitrate != 0 ? std::to_string(d.dbitrate) : std::string("<data bit rate>")) + " fd on";
  // A controller left bus-off stays off without it: 100 ms, then it rejoins by itself.
  return cmd + " restart-ms 100";
}

void check_can_link(const config::CanDevice& d, const hal::socketcan::CanInterfaceInfo& info, RowMaker& rows) {
  using hal::socketcan::ControllerState;
  const std::string item = "link " + d.interface;
  if (info.kind == "can") {
    const std::string reset = "ip link set " + d.interface + " down && " + can_up_command(d);
    if (!info.up) {
      rows.add(item, CheckStatus::Fail, "down", d.interface_at, can_up_command(d));
      return;
    }
    std::vector<std::string> wrong;
    if (d.bitrate != 0 && info.bitrate != d.bitrate)
      wrong.push_back("bit rate " + bits_per_second(info.bitrate) + ", the bench wants " + bits_per_second(d.bitrate));
    if (d.fd && !info.fd_mode) wrong.push_back("CAN FD is off, the bench wants fd = true");
    if (d.fd && d.dbitrate != 0 && info.data_bitrate != d.dbitrate)
      wrong.push_back("data bit rate " + bits_per_second(info.data_bitrate) + ", the bench wants " + bits_per_second(d.dbitrate));
    if (!wrong.empty()) {
      std::string detail;
      for (const auto& w : wrong) detail += (detail.empty() ? "" : "; ") + w;
      rows.add(item, CheckStatus::Fail, detail, d.interface_at, reset);
      return;
    }
    std::string detail = "up, " + bits_per_second(info.bitrate);
    if (info.fd_mode) detail += ", FD data " + bits_per_second(info.data_bitrate);
    if (info.fd_mode && !d.fd) detail += " (FD on; the bench's classic frames pass)";
    detail += std::string(", ") + to_string(info.state);
    if (info.berr_counter) detail += " (tx errors " + std::to_string(info.tx_errors) + ", rx " + std::to_string(info.rx_errors) + ")";
    const std::string bus_fix = "check the bus: both ends terminated (120 Ohm), wiring, every node at " +
                                bits_per_second(info.bitrate) + "; then ip link set " + d.interface + " type can restart";
    switch (info.state) {
      case ControllerState::BusOff: rows.add(item, CheckStatus::Fail, detail, d.interface_at, bus_fix); break;
      case ControllerState::ErrorPassive:
      case ControllerState::ErrorWarning: rows.add(item, CheckStatus::Warn, detail, d.interface_at, bus_fix); break;
      case ControllerState::Stopped: rows.add(item, CheckStatus::Fail, detail, d.interface_at, reset); break;
      default: rows.add(item, CheckStatus::Ok, detail, d.interface_at); break;
    }
    return;
  }
  // Virtual CAN (vcan, vxcan): no controller, no bit timing; FD frames pass when the MTU is 72.
  if (!info.up) {
    rows.add(item, CheckStatus::Fail, "down", d.interface_at, "ip link set " + d.interface + " up");
    return;
  }
  if (d.fd && !info.carries_fd()) {
    rows.add(item, CheckStatus::Fail, "MTU " + std::to_string(info.mtu) + ": CAN FD frames do not pass, the bench wants fd = true",
             d.interface_at, "ip link set " + d.interface + " down && ip link set " + d.interface + " mtu 72 up");
    return;
  }
  rows.add(item, CheckStatus::Ok, "up, virtual (" + info.kind + ", MTU " + std::to_string(info.mtu) + "): no bit rate to check",
           d.interface_at);
}

// ---- GPIO ---------------------------------------------------------------------------------

std::string gpio_access_fix() {
  return "usermod -aG gpio inertia, with the udev rule of daq/README.md giving group gpio the chip "
         "(SUBSYSTEM==\"gpio\", KERNEL==\"gpiochip*\", GROUP=\"gpio\", MODE=\"0660\")";
}

// ---- Modbus -------------------------------------------------------------------------------

const char* type_name(config::RegisterType t) {
  switch (t) {
    case config::RegisterType::U16: return "u16";
    case config::RegisterType::I16: return "i16";
    case config::RegisterType::U32: return "u32";
    case config::RegisterType::I32: return "i32";
    case config::RegisterType::F32: return "f32";
  }
  return "?";
}

/// A serial port that cannot be opened, before libmodbus says so less clearly ("modbus_connect:
/// No such file or directory"). True when the row was added.
bool check_serial_port(const config::ModbusDevice& m, RowMaker& rows) {
  const std::string item = "serial port " + m.serial_port;
  struct stat st{};
  if (::stat(m.serial_port.c_str(), &st) != 0) {
    rows.add(item, CheckStatus::Fail, std::string("does not exist (") + std::strerror(errno) + ")", m.endpoint_at,
             "ls -l /dev/serial/by-id/   # the adapters plugged in; name one of them in serial_port =");
    return true;
  }
  if (!S_ISCHR(st.st_mode)) {
    rows.add(item, CheckStatus::Fail, "is not a character device (a serial port is)", m.endpoint_at,
             "ls -l /dev/serial/by-id/   # name the adapter in serial_port =");
    return true;
  }
  if (::access(m.serial_port.c_str(), R_OK | W_OK) != 0) {
    rows.add(item, CheckStatus::Fail, std::string("cannot be opened for reading and writing (") + std::strerror(errno) + ")",
             m.endpoint_at, "usermod -aG dialout inertia   # serial ports belong to group dialout");
    return true;
  }
  return false;
}

std::string modbus_connect_fix(const config::ModbusDevice& m, const hal::modbus::ModbusConfig& c) {
  if (c.is_rtu())
    return "check that the controller is on and wired to " + m.serial_port +
           " (A/B not swapped on RS-485); stty -F " + m.serial_port + " shows the line";
  return "is the controller on, in Modbus TCP mode, listening on port " + std::to_string(c.port) + "? nc -zv " + c.host +
         " " + std::to_string(c.port) + "; ip route get " + c.host;
}

std::string modbus_read_fix(const config::ModbusDevice& m, const config::ModbusRegister& r, int err) {
  const bool rtu = m.transport == config::ModbusTransport::Rtu;
  if (err >= EMBXILFUN && err <= EMBXGTAR)
    return "the controller refused it: check address " + std::to_string(r.address) + " and kind = \"" +
           (r.kind == config::RegisterKind::Input ? "input" : "holding") + "\" against its register table";
  if (err == ENOTCONN) return "not asked: the link dropped at an earlier request (the row above says why)";
  if (err == ETIMEDOUT && rtu)
    return "no answer: unit_id " + std::to_string(m.unit_id) + ", baud " + std::to_string(m.baud) +
           ", parity and data/stop bits must match the controller's settings";
  if (err == ETIMEDOUT) return "no answer: check unit_id " + std::to_string(m.unit_id) + " against the controller's settings";
  if (err >= EMBBADCRC && err <= EMBBADSLAVE)
    return rtu ? "garbled answers: baud " + std::to_string(m.baud) + ", parity and data/stop bits must match the controller's"
               : "the answer is not Modbus TCP: is port " + std::to_string(m.port) + " the controller's Modbus port?";
  return rtu ? "the serial line failed: is the adapter still plugged in? (ls -l " + m.serial_port + ")"
             : "the controller closed the connection: is port " + std::to_string(m.port) +
                   " its Modbus TCP port, and does it take another client?";
}

}  // namespace

const char* to_string(CheckStatus status) noexcept {
  switch (status) {
    case CheckStatus::Ok: return "ok";
    case CheckStatus::Warn: return "warn";
    case CheckStatus::Fail: return "FAIL";
  }
  return "?";
}

std::vector<CheckRow> check_can_device(const config::CanDevice& d) {
  RowMaker rows{d.name, "CAN", d.availability.optional, {}};
  bool socketcan = false;
  {
    const hal::UniqueFd probe(::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW));
    const int err = errno;
    socketcan = probe.valid();
    if (socketcan) {
      rows.add("SocketCAN", CheckStatus::Ok, "AF_CAN, CAN_RAW", d.interface_at);
    } else if (err == EAFNOSUPPORT) {
      rows.add("SocketCAN", CheckStatus::Fail, "this kernel has no SocketCAN (AF_CAN: " + std::string(std::strerror(err)) + ")",
               d.interface_at, "modprobe can_raw   # the kernel needs CONFIG_CAN and CONFIG_CAN_RAW");
    } else {
      rows.add("SocketCAN", CheckStatus::Fail, std::string("socket(PF_CAN, SOCK_RAW, CAN_RAW): ") + std::strerror(err),
               d.interface_at, "the service must allow AF_CAN (RestrictAddressFamilies= of inertia-daqd.service)");
    }
  }
  hal::socketcan::CanInterfaceInfo info;
  std::string why;
  if (!hal::socketcan::query_can_interface(d.interface, &info, &why)) {
    rows.add("interface " + d.interface, CheckStatus::Fail, why, d.interface_at);
    return std::move(rows.rows);
  }
  if (!info.present) {
    rows.add("interface " + d.interface, CheckStatus::Fail, "no such network interface", d.interface_at,
             "plug in the adapter and load its driver; ip -details link show type can lists the CAN interfaces "
             "(name one in interface =); without hardware: ip link add dev " + d.interface + " type vcan");
    return std::move(rows.rows);
  }
  if (!info.is_can()) {
    rows.add("interface " + d.interface, CheckStatus::Fail,
             "is not a CAN interface (" + (info.kind.empty() ? std::string("no link kind, e.g. loopback or Ethernet") : "kind " + info.kind) + ")",
             d.interface_at, "ip -details link show type can   # name a CAN interface in interface =");
    return std::move(rows.rows);
  }
  rows.add("interface " + d.interface, CheckStatus::Ok, "present (" + info.kind + ")", d.interface_at);
  check_can_link(d, info, rows);
  if (!socketcan) return std::move(rows.rows);
  auto device = hal::socketcan::CanDevice::open_interface(to_hal(d), &why);
  if (!device) {
    rows.add("CAN_RAW socket", CheckStatus::Fail, why, d.interface_at);
  } else if (device->configure() != hal::Step::Ok) {
    rows.add("CAN_RAW socket", CheckStatus::Fail, device->last_error(), d.interface_at);
  } else {
    rows.add("CAN_RAW socket", CheckStatus::Ok,
             "bound, " + std::to_string(d.signals.size()) + " signals filtered" + (d.fd ? ", FD frames on" : ""), d.interface_at);
  }
  return std::move(rows.rows);
}

std::vector<CheckRow> check_gpiod_encoder(const config::GpiodEncoder& e) {
  RowMaker rows{e.name, "GPIO", e.availability.optional, {}};
  const char* line_keys[4] = {"line_a", "line_b", "line_marker", "line_trigger"};
  const int line_offsets[4] = {e.line_a, e.line_b, e.line_marker, e.line_trigger};
  std::vector<unsigned> offsets;
  std::vector<int> key_of;
  for (int i = 0; i < 4; ++i) {
    if (line_offsets[i] < 0) continue;
    offsets.push_back(static_cast<unsigned>(line_offsets[i]));
    key_of.push_back(i);
  }
  const hal::gpiod::ChipProbe chip = hal::gpiod::probe_lines(e.chip, offsets, kConsumer);
  const std::string chip_item = "chip " + e.chip;
  if (!chip.opened) {
    const int err = chip.open_errno;
    if (err == EACCES || err == EPERM) {
      rows.add(chip_item, CheckStatus::Fail, std::string("cannot be opened: ") + std::strerror(err), e.chip_at, gpio_access_fix());
    } else if (!chip.any_chip) {
      rows.add(chip_item, CheckStatus::Fail, "no GPIO chip: this machine has no /dev/gpiochip* at all", e.chip_at,
               "load the board's GPIO driver (gpiodetect lists the chips); for a test without hardware: modprobe gpio-sim "
               "(daq/README.md)");
    } else {
      rows.add(chip_item, CheckStatus::Fail, std::string("no such GPIO chip (") + std::strerror(err) + ")", e.chip_at,
               "gpiodetect   # the chips this machine has; name one in chip =");
    }
    return std::move(rows.rows);
  }
  rows.add(chip_item, CheckStatus::Ok, chip.name + " [" + chip.label + "], " + std::to_string(chip.lines) + " lines", e.chip_at);
  for (std::size_t i = 0; i < chip.probes.size(); ++i) {
    const hal::gpiod::LineProbe& p = chip.probes[i];
    const int key = key_of[i];
    const std::string item = "line " + std::to_string(p.offset) + " (" + line_keys[key] + ")";
    const SourcePosition& at = e.line_at[key];
    if (!p.exists) {
      rows.add(item, CheckStatus::Fail, "the chip has lines 0.." + std::to_string(chip.lines - 1) + " only", at,
               std::string("gpioinfo ") + chip.name + "   # set " + line_keys[key] + " = to the line the signal is wired to");
    } else if (p.used && !p.requestable) {
      rows.add(item, CheckStatus::Fail, "held by '" + (p.consumer.empty() ? std::string("?") : p.consumer) + "'", at,
               std::string("gpioinfo ") + chip.name + "   # stop the holder, or free the pin from its driver (device tree)");
    } else if (!p.requestable) {
      const bool access = p.request_errno == EACCES || p.request_errno == EPERM;
      rows.add(item, CheckStatus::Fail, std::string("both-edge event request refused: ") + std::strerror(p.request_errno), at,
               access ? gpio_access_fix()
                      : std::string("gpioinfo ") + chip.name + "   # the line must be an input that can raise interrupts");
    } else {
      rows.add(item, CheckStatus::Ok, "free, both-edge events", at);
    }
  }
  return std::move(rows.rows);
}

namespace {

// The heartbeat the controller's communication-loss action watches: the daemon must be able to
// write it (a write the controller does not take would leave the bench stopping at every start,
// or, worse, a watchdog that was never armed), and what the controller needs to stop (its timeout
// plus its own stop time) must fit the bench's stop distance.
void check_heartbeat(const config::ModbusDevice& m, std::size_t index, hal::modbus::ModbusController& controller,
                     const config::BenchConfig* bench, RowMaker& rows) {
  const config::ModbusRegister& h = m.registers[index];
  const std::string item = "heartbeat " + h.name;
  if (!m.writes_enabled) {
    rows.add(item, CheckStatus::Warn, "writes_enabled = false: the daemon writes no heartbeat (and commands nothing)", h.where);
    return;
  }
  const hal::modbus::RegisterSpec& spec = controller.config().map.registers[index];
  std::uint16_t words[2] = {0, 0};
  const int n = hal::modbus::word_count(spec.type);
  double next = h.min;
  if (controller.link().read_registers(spec.kind, spec.address, std::span<std::uint16_t>(words, static_cast<std::size_t>(n))) == n) {
    const double held = hal::modbus::decode(spec, words);
    next = std::isfinite(held) && held + std::abs(h.scale) <= h.max ? held + std::abs(h.scale) : h.min;
  }
  const hal::modbus::WriteResult w = controller.write(index, next, hal::modbus::Ramp::Immediate);
  if (w.status != hal::modbus::WriteStatus::Written) {
    rows.add(item, CheckStatus::Fail, std::string("writing ") + number(next) + ": " + hal::modbus::to_string(w.status), h.where,
             "the daemon must be able to write the heartbeat register: check its address and type against the "
             "controller's register table, and that the controller accepts writes from this PC");
    return;
  }
  const double stop_s = h.heartbeat_timeout_s + h.heartbeat_stop_s;
  std::string detail = "written " + number(w.written) + " and read back; the controller stops " + number(h.heartbeat_timeout_s) +
                       " s after the daemon's last heartbeat and is at rest " + number(stop_s) + " s after it";
  if (bench == nullptr || !bench->stop_within_s) {
    rows.add(item, CheckStatus::Warn, detail + "; the bench gives no stop_within_s to hold that against", h.where,
             "set [bench] stop_within_s: the longest the bench's machinery may go on after the daemon dies");
  } else if (stop_s > *bench->stop_within_s) {
    rows.add(item, CheckStatus::Fail, detail + ", more than the bench's stop_within_s = " + number(*bench->stop_within_s) + " s", h.where,
             "shorten the controller's communication-loss timeout (and timeout_s here), or its stop time");
  } else {
    rows.add(item, CheckStatus::Ok, detail + ", within the bench's stop_within_s = " + number(*bench->stop_within_s) + " s", h.where);
  }
}

}  // namespace

std::vector<CheckRow> check_modbus_device(const config::ModbusDevice& m, const config::BenchConfig* bench) {
  const bool rtu = m.transport == config::ModbusTransport::Rtu;
  RowMaker rows{m.name, rtu ? "Modbus RTU" : "Modbus TCP", m.availability.optional, {}};
  if (rtu && check_serial_port(m, rows)) return std::move(rows.rows);
  const hal::modbus::ModbusConfig config = to_hal(m);
  std::string why;
  auto controller = hal::modbus::ModbusController::connect(config, &why);
  const std::string item = "connect " + config.endpoint();
  if (!controller) {
    rows.add(item, CheckStatus::Fail, why, m.endpoint_at, modbus_connect_fix(m, config));
    return std::move(rows.rows);
  }
  rows.add(item, CheckStatus::Ok, rtu ? "port open, unit " + std::to_string(m.unit_id) : "connected, unit " + std::to_string(m.unit_id),
           m.endpoint_at);
  // One request per register, so that a refused address or a bad value names its register
  // (the daemon's poll groups neighbours into one request).
  for (std::size_t i = 0; i < m.registers.size(); ++i) {
    const config::ModbusRegister& r = m.registers[i];
    const hal::modbus::RegisterSpec& spec = config.map.registers[i];
    const std::string reg_item = "register " + r.name;
    const std::string where_in_map = std::string(r.kind == config::RegisterKind::Input ? "input " : "holding ") +
                                     std::to_string(r.address) + " " + type_name(r.type);
    std::uint16_t words[2] = {0, 0};
    const int n = hal::modbus::word_count(spec.type);
    if (controller->link().read_registers(spec.kind, spec.address, std::span<std::uint16_t>(words, static_cast<std::size_t>(n))) != n) {
      const int err = errno;
      rows.add(reg_item, CheckStatus::Fail, where_in_map + ": " + modbus_strerror(err), r.where, modbus_read_fix(m, r, err));
      continue;
    }
    const double value = hal::modbus::decode(spec, words);
    const std::string shown = where_in_map + " = " + number(value) + (r.unit.empty() ? "" : " " + r.unit);
    // A setpoint outside its write limits is as wrong as a reading outside its range.
    const double lo = r.writable && std::isinf(r.range_min) ? r.min : r.range_min;
    const double hi = r.writable && std::isinf(r.range_max) ? r.max : r.range_max;
    if (!std::isfinite(value)) {
      rows.add(reg_item, CheckStatus::Fail, shown + ": not a number", r.where,
               "check type and word_order of this register against the controller's register table");
    } else if (value < lo || value > hi) {
      rows.add(reg_item, CheckStatus::Fail, shown + ": outside [" + number(lo) + ", " + number(hi) + "]", r.where,
               "check scale, offset, type and word_order of this register, or the controller itself");
    } else {
      rows.add(reg_item, CheckStatus::Ok, shown, r.where);
    }
  }
  if (const auto h = config::heartbeat_register(m)) check_heartbeat(m, *h, *controller, bench, rows);
  return std::move(rows.rows);
}

std::vector<CheckRow> check_bench(const config::BenchConfig& bench) {
  std::vector<CheckRow> rows;
  auto append = [&rows](std::vector<CheckRow> more) { rows.insert(rows.end(), more.begin(), more.end()); };
  for (const auto& d : bench.can_devices) append(check_can_device(d));
  for (const auto& e : bench.gpiod_encoders) append(check_gpiod_encoder(e));
  for (const auto& m : bench.modbus_devices) append(check_modbus_device(m, &bench));
  return rows;
}

int check_exit_status(const std::vector<CheckRow>& rows) {
  for (const CheckRow& r : rows)
    if (r.status == CheckStatus::Fail && !r.optional) return kExitBadInput;
  return kExitOk;
}

std::string format_failure(const CheckRow& row) {
  std::string where = row.where.file;
  if (row.where.line > 0) where += ":" + std::to_string(row.where.line);
  if (row.where.line > 0 && row.where.column > 0) where += ":" + std::to_string(row.where.column);
  std::string s = (where.empty() ? "" : where + ": ") + "device '" + row.device + "' (" + row.kind + ") " + row.item + ": " +
                  row.detail;
  if (!row.fix.empty()) s += "\n  fix: " + row.fix;
  return s;
}

void print_check_table(std::ostream& out, const config::BenchConfig& bench, const std::vector<CheckRow>& rows) {
  out << "inertia-daqd --check: bench '" << bench.name << "' (" << bench.file.string() << ")"
      << (bench.simulated ? ", backend = \"sim\": these are the real-bench tables; the simulator does not use them" : "")
      << "\n";
  if (rows.empty()) {
    out << "no [[can_device]], [[gpiod_encoder]] or [[modbus_device]]: nothing to check\n";
    return;
  }
  const std::vector<std::string> head{"DEVICE", "TYPE", "CHECK", "RESULT", "DETAIL"};
  std::vector<std::array<std::string, 5>> cells;
  for (const CheckRow& r : rows)
    cells.push_back({r.device + (r.optional ? " (optional)" : ""), r.kind, r.item, to_string(r.status), r.detail});
  std::array<std::size_t, 4> width{};
  for (std::size_t c = 0; c < 4; ++c) {
    width[c] = head[c].size();
    for (const auto& row : cells) width[c] = std::max(width[c], row[c].size());
  }
  const std::size_t indent = width[0] + width[1] + width[2] + width[3] + 8;
  auto line = [&](const std::array<std::string, 5>& c) {
    for (std::size_t i = 0; i < 4; ++i) out << std::left << std::setw(static_cast<int>(width[i])) << c[i] << "  ";
    out << c[4] << "\n";
  };
  line({head[0], head[1], head[2], head[3], head[4]});
  for (std::size_t i = 0; i < rows.size(); ++i) {
    line(cells[i]);
    const CheckRow& r = rows[i];
    if (r.status == CheckStatus::Ok) continue;
    if (!r.where.file.empty())
      out << std::string(indent, ' ') << "at " << r.where.file << ":" << r.where.line << ":" << r.where.column << "\n";
    if (!r.fix.empty()) out << std::string(indent, ' ') << "fix: " << r.fix << "\n";
  }
  std::vector<std::string> failed, optional_failed;
  for (const CheckRow& r : rows) {
    if (r.status != CheckStatus::Fail) continue;
    auto& list = r.optional ? optional_failed : failed;
    if (std::find(list.begin(), list.end(), r.device) == list.end()) list.push_back(r.device);
  }
  auto join = [](const std::vector<std::string>& names) {
    std::string s;
    for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
    return s;
  };
  if (!optional_failed.empty())
    out << "optional, not ready: " << join(optional_failed) << " (the daemon starts without them, degraded)\n";
  if (failed.empty()) out << "every required device is ready\n";
  else out << "required, not ready: " << join(failed) << " (exit status 2)\n";
}

int run_device_check(const std::string& config_path, std::ostream& out) {
  const config::BenchConfig bench = config::load_bench_config(config_path);
  const std::vector<CheckRow> rows = check_bench(bench);
  print_check_table(out, bench, rows);
  return check_exit_status(rows);
}

}  // namespace inertia::daq
