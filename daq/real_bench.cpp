#include "daq/real_bench.hpp"

namespace inertia::daq {
namespace {

hal::socketcan::CanDeviceConfig to_hal(const config::CanDevice& d) {
  hal::socketcan::CanDeviceConfig c;
  c.name = d.name;
  c.interface = d.interface;
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
    c.map.signals.push_back(h);
  }
  return c;
}

hal::modbus::ModbusConfig to_hal(const config::ModbusDevice& d) {
  hal::modbus::ModbusConfig c;
  c.name = d.name;
  c.host = d.host;
  c.port = d.port;
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
    }
    c.map.registers.push_back(s);
  }
  return c;
}

}  // namespace

std::vector<std::unique_ptr<Sampler>> open_real_bench(const config::BenchConfig& bench, std::size_t ring_capacity,
                                                      std::string* why) {
  std::vector<std::unique_ptr<Sampler>> out;
  std::int32_t next_id = 1;
  auto fail = [&](const std::string& what) {
    if (why) *why = what;
    out.clear();
    return std::move(out);
  };
  for (const auto& d : bench.can_devices) {
    std::string reason;
    auto dev = hal::socketcan::CanDevice::open_interface(to_hal(d), &reason);
    if (!dev) return fail("device '" + d.name + "' (CAN " + d.interface + "): " + reason);
    std::vector<ChannelInfo> info;
    for (const auto& s : d.signals) info.push_back({s.name, s.unit, next_id++});
    auto slot = std::make_shared<DeviceSlot>(d.name, std::move(info), d.sample_rate_hz > 0 ? d.sample_rate_hz : bench.sample_rate_hz,
                                             ring_capacity);
    const int fd = dev->wait_fd();
    out.push_back(std::make_unique<DeviceSampler>(std::move(dev), std::vector<int>{fd}, slot, false));
  }
  for (const auto& e : bench.gpiod_encoders) {
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
    q.sample_rate_hz = e.line_trigger >= 0 ? 0.0 : bench.sample_rate_hz;
    std::string reason;
    auto dev = hal::gpiod::GpiodEncoderDevice::open(q, &reason);
    if (!dev) return fail("device '" + e.name + "' (GPIO " + e.chip + "): " + reason);
    std::vector<int> fds;
    for (int fd : dev->event_fds())
      if (fd >= 0) fds.push_back(fd);
    if (dev->tick_fd() >= 0) fds.push_back(dev->tick_fd());  // ticks go out while the encoder stands still
    // Sampled on the trigger line (the bench's sample clock) when there is one, else on ticks.
    const bool rows = e.line_trigger >= 0;
    std::vector<ChannelInfo> info{{"count", "1", next_id}, {"position", e.rotary ? "rad" : "m", next_id + 1}};
    next_id += 2;
    auto slot = std::make_shared<DeviceSlot>(e.name, std::move(info), bench.sample_rate_hz, ring_capacity);
    out.push_back(std::make_unique<DeviceSampler>(std::move(dev), std::move(fds), slot, rows));
  }
  for (const auto& m : bench.modbus_devices) {
    std::string reason;
    auto controller = hal::modbus::ModbusController::connect(to_hal(m), &reason);
    if (!controller) return fail("device '" + m.name + "' (Modbus " + m.host + ":" + std::to_string(m.port) + "): " + reason);
    std::vector<ChannelInfo> info;
    for (const auto& r : m.registers) info.push_back({r.name, r.unit, next_id++});
    auto slot = std::make_shared<DeviceSlot>(m.name, std::move(info), 1000.0 / m.poll_interval_ms, ring_capacity);
    out.push_back(std::make_unique<ModbusSampler>(std::move(controller), m.poll_interval_ms, slot));
  }
  if (out.empty() && why) *why = bench.file.string() + ": backend = \"real\" but no [[can_device]], [[gpiod_encoder]] or [[modbus_device]]";
  return out;
}

}  // namespace inertia::daq
