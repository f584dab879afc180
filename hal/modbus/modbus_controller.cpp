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
      if (!ok) continue;
      // A NaN or infinite register is no reading: marked invalid, as a failed request is.
      if (const auto reading = decode_reading(regs[i], words.subspan(static_cast<std::size_t>(regs[i].address - b.address)))) {
        v.value = *reading;
        v.valid = true;
      }
    }
  }
  return values_;
}

WriteResult ModbusController::write(std::string_view name, double value) {
  WriteResult result;
  const int index = config_.map.find(name);
  if (index < 0) {
    result.status = WriteStatus::UnknownRegister;
    return result;
  }
  const RegisterSpec& r = config_.map.registers[static_cast<std::size_t>(index)];
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
  const double limited = std::clamp(value, r.min, r.max);
  result.clamped = limited != value;
  std::uint16_t words[2] = {0, 0};
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
  const int n = word_count(r.type);
  if (link_->write_registers(r.address, std::span<const std::uint16_t>(words, static_cast<std::size_t>(n))) != n) {
    result.status = WriteStatus::LinkError;
    return result;
  }
  result.status = WriteStatus::Written;
  return result;
}

}  // namespace inertia::hal::modbus
