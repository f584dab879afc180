#include "daq/real_bench.hpp"

#include <algorithm>
#include <cmath>

#include "common/config/machine_safety.hpp"
#include "daq/device_check.hpp"

namespace inertia::daq {

hal::socketcan::CanDeviceConfig to_hal(const config::CanDevice& d) {
  hal::socketcan::CanDeviceConfig c;
  c.name = d.name;
  c.interface = d.interface;
  c.frame_rate_hz = d.sample_rate_hz;
  for (const auto& s : d.signals) {
    hal::socketcan::CanSignal h;
    h.name = s.name;
    h.id = s.id;
    h.extended = s.extended;
    h.byte_offset = static_cast<std::uint8_t>(s.byte_offset);
    h.bit_offset = static_cast<std::uint8_t>(s.bit_offset);
    h.bit_length = static_cast<std::uint8_t>(s.bit_length);
    h.byte_order = s.byte_order == config::ByteOrder::BigEndian ? hal::socketcan::ByteOrder::BigEndian
                                                                 : hal::socketcan::ByteOrder::LittleEndian;
    h.is_signed = s.is_signed;
    h.scale = s.scale;
    h.offset = s.offset;
    h.invalid_raw = s.invalid_raw;
    h.counter = s.counter;
    h.wraps = s.wraps;
    h.min = s.min;
    h.max = s.max;
    c.map.signals.push_back(h);
  }
  return c;
}

hal::modbus::ModbusConfig to_hal(const config::ModbusDevice& d) {
  hal::modbus::ModbusConfig c;
  c.name = d.name;
  c.host = d.host;
  c.port = d.port;
  if (d.transport == config::ModbusTransport::Rtu) {
    c.serial.device = d.serial_port;
    c.serial.baud = d.baud;
    c.serial.parity = d.parity == config::SerialParity::None ? 'N' : d.parity == config::SerialParity::Odd ? 'O' : 'E';
    c.serial.data_bits = d.data_bits;
    c.serial.stop_bits = d.stop_bits;
  }
  c.unit_id = d.unit_id;
  c.response_timeout_s = d.response_timeout_s;
  c.reconnect_initial_s = d.reconnect_initial_s;
  c.reconnect_max_s = d.reconnect_max_s;
  c.timeouts_before_reconnect = d.timeouts_before_reconnect;
  c.writes_enabled = d.writes_enabled;
  for (const auto& r : d.registers) {
    hal::modbus::RegisterSpec s;
    s.name = r.name;
    s.address = r.address;
    s.kind = r.kind == config::RegisterKind::Input ? hal::modbus::RegisterKind::Input : hal::modbus::RegisterKind::Holding;
    switch (r.type) {
      case config::RegisterType::U16: s.type = hal::modbus::DataType::UInt16; break;
      case config::RegisterType::I16: s.type = hal::modbus::DataType::Int16; break;
      case config::RegisterType::U32: s.type = hal::modbus::DataType::UInt32; break;
      case config::RegisterType::I32: s.type = hal::modbus::DataType::Int32; break;
      case config::RegisterType::F32: s.type = hal::modbus::DataType::Float32; break;
    }
    s.order = static_cast<hal::modbus::WordOrder>(static_cast<int>(r.order));
    s.scale = r.scale;
    s.offset = r.offset;
    s.writable = r.writable;
    if (r.writable) {
      s.min = r.min;
      s.max = r.max;
      s.max_rate = r.max_rate;
    }
    // Plausible readings: `range`, else a setpoint's write limits (as inertia-daqd --check has them).
    s.range_min = r.writable && std::isinf(r.range_min) ? r.min : r.range_min;
    s.range_max = r.writable && std::isinf(r.range_max) ? r.max : r.range_max;
    c.map.registers.push_back(s);
  }
  return c;
}

hal::gpiod::QuadratureConfig to_hal(const config::GpiodEncoder& e, double bench_sample_rate_hz) {
  hal::gpiod::QuadratureConfig q;
  q.name = e.name;
  q.chip = e.chip;
  q.line_a = static_cast<unsigned>(e.line_a);
  q.line_b = static_cast<unsigned>(e.line_b);
  q.line_marker = e.line_marker;
  q.line_trigger = e.line_trigger;
  q.active_low = e.active_low;
  q.resolution = e.resolution;
  q.edge_latency_ns = e.edge_latency_ns;
  // Without a trigger line the device samples itself on the bench's rate (zero-order hold).
  q.sample_rate_hz = e.line_trigger >= 0 ? 0.0 : bench_sample_rate_hz;
  return q;
}

namespace {


/// Samples in a row that make a channel stuck, from its stuck_after_s at its device's rate (0: off).
std::uint32_t stuck_samples(double stuck_after_s, double rate_hz) {
  return stuck_after_s > 0.0 ? static_cast<std::uint32_t>(std::max(2.0, std::ceil(stuck_after_s * rate_hz))) : 0u;
}

/// The start-up message for a device that did not open: the device check's first failure for
/// it (bench-file position, what, fix) when the check finds one, else the open call's reason.
std::string diagnose(const std::vector<CheckRow>& rows, const std::string& fallback) {
  for (const CheckRow& row : rows)
    if (row.status == CheckStatus::Fail) return format_failure(row);
  return fallback;
}

}  // namespace

RealBench open_real_bench(const config::BenchConfig& bench, std::size_t ring_capacity, std::shared_ptr<const LifeSign> life,
                          std::string* why) {
  RealBench out;
  // Channel ids stay those of the full bench when an optional device is left out.
  std::int32_t next_id = 1;
  // false: a required device failed (out is cleared, why says which).
  auto left_out = [&](const config::DeviceAvailability& availability, const std::string& name, std::string reason) {
    if (availability.optional) {
      out.left_out.push_back({name, std::move(reason)});
      return true;
    }
    if (why) *why = std::move(reason);
    out.samplers.clear();
    out.left_out.clear();
    out.ports.clear();
    return false;
  };
  for (const auto& d : bench.can_devices) {
    std::string reason;
    hal::socketcan::CanDeviceConfig config = to_hal(d);
    const double rate_hz = d.sample_rate_hz > 0 ? d.sample_rate_hz : bench.sample_rate_hz;
    config.frame_rate_hz = rate_hz;
    auto dev = hal::socketcan::CanDevice::open_interface(config, &reason);
    if (!dev) {
      if (!left_out(d.availability, d.name, diagnose(check_can_device(d), "device '" + d.name + "' (CAN " + d.interface + "): " + reason)))
        return out;
      next_id += static_cast<std::int32_t>(d.signals.size());
      continue;
    }
    std::vector<ChannelInfo> info;
    for (const auto& s : d.signals) info.push_back({s.name, s.unit, next_id++});
    auto slot = std::make_shared<DeviceSlot>(d.name, std::move(info), rate_hz, ring_capacity);
    slot->silent_timeout_ns = hal::seconds_to_ns(d.availability.silent_timeout_s);
    slot->latency_floor_ns = d.availability.latency_floor_ns;
    for (const auto& s : d.signals) slot->stuck_samples.push_back(stuck_samples(s.stuck_after_s, rate_hz));
    const int fd = dev->wait_fd();
    out.samplers.push_back(std::make_unique<DeviceSampler>(std::move(dev), std::vector<int>{fd}, slot, false));
  }
  for (const auto& e : bench.gpiod_encoders) {
    std::string reason;
    auto dev = hal::gpiod::GpiodEncoderDevice::open(to_hal(e, bench.sample_rate_hz), &reason);
    if (!dev) {
      if (!left_out(e.availability, e.name, diagnose(check_gpiod_encoder(e), "device '" + e.name + "' (GPIO " + e.chip + "): " + reason)))
        return out;
      next_id += 2;
      continue;
    }
    std::vector<int> fds;
    for (int fd : dev->event_fds())
      if (fd >= 0) fds.push_back(fd);
    if (dev->tick_fd() >= 0) fds.push_back(dev->tick_fd());  // ticks go out while the encoder stands still
    // Sampled on the trigger line (the bench's sample clock) when there is one, else on ticks.
    const bool rows = e.line_trigger >= 0;
    std::vector<ChannelInfo> info{{"count", "1", next_id}, {"position", e.rotary ? "rad" : "m", next_id + 1}};
    next_id += 2;
    auto slot = std::make_shared<DeviceSlot>(e.name, std::move(info), bench.sample_rate_hz, ring_capacity);
    slot->silent_timeout_ns = hal::seconds_to_ns(e.availability.silent_timeout_s);
    slot->latency_floor_ns = e.availability.latency_floor_ns;
    out.samplers.push_back(std::make_unique<DeviceSampler>(std::move(dev), std::move(fds), slot, rows));
  }
  for (const auto& m : bench.modbus_devices) {
    std::string reason;
    const hal::modbus::ModbusConfig config = to_hal(m);
    auto controller = hal::modbus::ModbusController::connect(config, &reason);
    if (!controller) {
      const std::string fallback = "device '" + m.name + "' (Modbus " + config.endpoint() + "): " + reason;
      if (!left_out(m.availability, m.name, diagnose(check_modbus_device(m), fallback))) return out;
      next_id += static_cast<std::int32_t>(m.registers.size());
      continue;
    }
    std::vector<ChannelInfo> info;
    for (const auto& r : m.registers) info.push_back({r.name, r.unit, next_id++});
    auto slot = std::make_shared<DeviceSlot>(m.name, std::move(info), 1000.0 / m.poll_interval_ms, ring_capacity);
    slot->silent_timeout_ns = hal::seconds_to_ns(m.availability.silent_timeout_s);
    slot->latency_floor_ns = m.availability.latency_floor_ns;
    for (const auto& r : m.registers) slot->stuck_samples.push_back(stuck_samples(r.stuck_after_s, slot->nominal_rate_hz));
    std::vector<ControllerPort::SafeValue> safe;
    for (std::size_t r = 0; r < m.registers.size(); ++r)
      if (m.writes_enabled && m.registers[r].safe) safe.push_back({r, *m.registers[r].safe});
    std::optional<ControllerPort::Heartbeat> heartbeat;
    if (const auto h = config::heartbeat_register(m); h && m.writes_enabled) {
      const config::ModbusRegister& reg = m.registers[*h];
      heartbeat = ControllerPort::Heartbeat{*h, hal::seconds_to_ns(reg.heartbeat_period_s), reg.min, reg.max, std::abs(reg.scale),
                                            hal::seconds_to_ns(reg.heartbeat_timeout_s)};
    }
    auto port = std::make_shared<ControllerPort>(m.name, std::move(safe), heartbeat, life);
    out.ports[m.name] = port;
    out.samplers.push_back(std::make_unique<ModbusSampler>(std::move(controller), m.poll_interval_ms, slot, port));
  }
  if (out.samplers.empty() && why) {
    if (out.left_out.empty()) {
      *why = bench.file.string() + ": backend = \"real\" but no [[can_device]], [[gpiod_encoder]] or [[modbus_device]]";
    } else {
      *why = "no device of the bench could be opened (all are optional):";
      for (const LeftOutDevice& d : out.left_out) *why += "\n  " + d.why;
    }
  }
  return out;
}

}  // namespace inertia::daq
