#include "hal/modbus/modbus_controller.hpp"

#include <algorithm>
#include <cmath>

#include "hal/device.hpp"

namespace inertia::hal::modbus {

const char* to_string(WriteStatus status) noexcept {
  switch (status) {
    case WriteStatus::Written: return "written";
    case WriteStatus::Disabled: return "writes are disabled in the config";
    case WriteStatus::NotWritable: return "register is not writable";
    case WriteStatus::UnknownRegister: return "no such register";
    case WriteStatus::NotFinite: return "value is not finite";
    case WriteStatus::LinkError: return "link error";
    case WriteStatus::NotConfirmed: return "not confirmed: the register read back holds another value";
  }
  return "?";
}

std::unique_ptr<ModbusController> ModbusController::connect(const ModbusConfig& config, std::string* why) {
  auto link = ModbusLink::connect(config, why);
  if (!link) return nullptr;
  return std::unique_ptr<ModbusController>(new ModbusController(config, std::move(link)));
}

ModbusController::ModbusController(ModbusConfig config, std::unique_ptr<ModbusLink> link)
    : config_(std::move(config)), link_(std::move(link)) {
  const auto& regs = config_.map.registers;
  std::vector<std::size_t> order(regs.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::pair(regs[a].kind, regs[a].address) < std::pair(regs[b].kind, regs[b].address);
  });
  // Only adjacent or overlapping registers share a request: reading a gap may hit addresses the
  // device does not have (ILLEGAL DATA ADDRESS for the whole request).
  for (std::size_t i : order) {
    const RegisterSpec& r = regs[i];
    const int end = r.address + word_count(r.type);
    if (!blocks_.empty()) {
      Block& b = blocks_.back();
      if (b.kind == r.kind && r.address <= b.address + b.words &&
          std::max(end, b.address + b.words) - b.address <= kMaxWordsPerRequest) {
        b.words = std::max(end, b.address + b.words) - b.address;
        b.registers.push_back(i);
        continue;
      }
    }
    blocks_.push_back(Block{r.kind, r.address, end - r.address, {i}});
  }
  values_.resize(regs.size());
  for (std::size_t i = 0; i < regs.size(); ++i) values_[i].name = regs[i].name;
  words_.resize(kMaxWordsPerRequest);
  last_written_.resize(regs.size());
  last_write_ns_.resize(regs.size(), 0);
}

std::span<const PolledValue> ModbusController::poll() {
  const auto& regs = config_.map.registers;
  for (const Block& b : blocks_) {
    const std::span<std::uint16_t> words(words_.data(), static_cast<std::size_t>(b.words));
    const bool ok = link_->read_registers(b.kind, b.address, words) == b.words;
    const std::int64_t t_ns = monotonic_now_ns();
    for (std::size_t i : b.registers) {
      PolledValue& v = values_[i];
      v.t_ns = t_ns;
      v.valid = false;
      v.out_of_range = false;
      if (!ok) continue;
      // A NaN or infinite register is no reading: marked invalid, as a failed request is.
      if (const auto reading = decode_reading(regs[i], words.subspan(static_cast<std::size_t>(regs[i].address - b.address)))) {
        v.value = *reading;
        // Implausible: kept as read, marked, counted.
        v.out_of_range = *reading < regs[i].range_min || *reading > regs[i].range_max;
        v.valid = !v.out_of_range;
        if (v.out_of_range) ++range_faults_;
      }
    }
  }
  return values_;
}

WriteResult ModbusController::write(std::string_view name, double value, Ramp ramp) {
  const int index = config_.map.find(name);
  if (index < 0) {
    WriteResult result;
    result.status = WriteStatus::UnknownRegister;
    return result;
  }
  return write(static_cast<std::size_t>(index), value, ramp);
}

WriteResult ModbusController::write(std::size_t index, double value, Ramp ramp) {
  WriteResult result;
  if (index >= config_.map.registers.size()) {
    result.status = WriteStatus::UnknownRegister;
    return result;
  }
  const RegisterSpec& r = config_.map.registers[index];
  if (!config_.writes_enabled) {
    result.status = WriteStatus::Disabled;
    return result;
  }
  if (!r.writable) {
    result.status = WriteStatus::NotWritable;
    return result;
  }
  if (!std::isfinite(value)) {
    result.status = WriteStatus::NotFinite;
    return result;
  }
  const int n = word_count(r.type);
  double limited = std::clamp(value, r.min, r.max);
  result.clamped = limited != value;
  std::uint16_t words[2] = {0, 0};
  const std::int64_t now_ns = monotonic_now_ns();
  std::optional<double> from;
  if (ramp == Ramp::Limited && std::isfinite(r.max_rate)) {
    from = last_written_[index];
    if (!from) {  // first write: ramp from what the device holds now
      if (link_->read_registers(r.kind, r.address, std::span<std::uint16_t>(words, static_cast<std::size_t>(n))) != n) {
        result.status = WriteStatus::LinkError;
        return result;
      }
      from = decode(r, std::span<const std::uint16_t>(words, static_cast<std::size_t>(n)));
    }
    const double dt_s = last_written_[index] ? std::min(static_cast<double>(now_ns - last_write_ns_[index]) * 1e-9, kMaxRampStepS)
                                             : kMaxRampStepS;
    const double step = r.max_rate * dt_s;
    if (std::abs(limited - *from) > step) {
      limited = *from + (limited > *from ? step : -step);
      result.rate_limited = true;
    }
  }
  result.written = encode(r, limited, words);
  // Rounding to the register's resolution may land just past a limit that lies between two
  // steps: take the step on the inside instead.
  if (result.written > r.max || result.written < r.min) {
    const double inward = result.written > r.max ? -1.0 : 1.0;
    const double next = r.type == DataType::Float32
                            ? std::nextafter(static_cast<float>((result.written - r.offset) / r.scale),
                                             static_cast<float>(inward * r.scale > 0 ? INFINITY : -INFINITY)) *
                                      r.scale + r.offset
                            : result.written + inward * std::abs(r.scale);
    result.written = encode(r, next, words);
  }
  // A ramp step smaller than the register's resolution rounds back to where it was: move one
  // count instead (the rate limit is then exceeded by less than one count), or it never arrives.
  if (result.rate_limited && from && result.written == encode(r, *from, std::span<std::uint16_t>(words_.data(), 2)) &&
      r.type != DataType::Float32) {
    result.written = encode(r, result.written + (value > *from ? 1.0 : -1.0) * std::abs(r.scale), words);
  }
  if (link_->write_registers(r.address, std::span<const std::uint16_t>(words, static_cast<std::size_t>(n))) != n) {
    last_written_[index].reset();  // what the device holds is unknown now
    result.status = WriteStatus::LinkError;
    return result;
  }
  // Confirmation: the device holds what was written, word for word (a controller that refuses or
  // overrides a value shows it here, and a later read of that register would too).
  std::uint16_t back[2] = {0, 0};
  const bool read = link_->read_registers(RegisterKind::Holding, r.address, std::span<std::uint16_t>(back, static_cast<std::size_t>(n))) == n;
  result.read_back = read ? decode(r, std::span<const std::uint16_t>(back, static_cast<std::size_t>(n))) : NAN;
  if (!read || back[0] != words[0] || (n == 2 && back[1] != words[1])) {
    last_written_[index].reset();
    result.status = WriteStatus::NotConfirmed;
    return result;
  }
  last_written_[index] = result.written;
  last_write_ns_[index] = now_ns;
  result.status = WriteStatus::Written;
  return result;
}

}  // namespace inertia::hal::modbus
