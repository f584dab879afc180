#include "common/lcm/message_decode.hpp"

#include <cstdint>
#include <limits>

namespace inertia {
namespace {

// A cursor over an LCM encoding (big-endian, lcm_coretypes.h): each read checks that its bytes
// are there; the first failure sticks and names the field.
class WireWalk {
 public:
  WireWalk(const void* data, std::size_t size) : bytes_(static_cast<const std::uint8_t*>(data)), size_(size) {}

  void skip(std::size_t n, const char* field) {
    if (!why_.empty()) return;
    if (n > size_ - pos_) {
      why_ = std::string(field) + " runs past the end of the message";
      return;
    }
    pos_ += n;
  }
  /// A count read from the message (int32); negative is an error.
  std::size_t count(const char* field) {
    if (!why_.empty()) return 0;
    if (size_ - pos_ < 4) {
      why_ = std::string(field) + " runs past the end of the message";
      return 0;
    }
    const std::int32_t n = static_cast<std::int32_t>((std::uint32_t{bytes_[pos_]} << 24) | (std::uint32_t{bytes_[pos_ + 1]} << 16) |
                                                     (std::uint32_t{bytes_[pos_ + 2]} << 8) | std::uint32_t{bytes_[pos_ + 3]});
    pos_ += 4;
    if (n < 0) {
      why_ = std::string(field) + " is negative (" + std::to_string(n) + ")";
      return 0;
    }
    return static_cast<std::size_t>(n);
  }
  /// An array of `rows` x `columns` elements of `element_size` bytes, checked before any
  /// multiplication can overflow.
  void array(std::size_t rows, std::size_t columns, std::size_t element_size, const char* field) {
    if (!why_.empty()) return;
    const std::size_t left = size_ - pos_;
    if (rows != 0 && columns != 0 && (columns > left / element_size || rows > left / (columns * element_size))) {
      why_ = std::string(field) + " holds more elements than the message has bytes";
      return;
    }
    pos_ += rows * columns * element_size;
  }
  /// LCM string: int32 length including the terminating NUL, then the bytes.
  void string(const char* field) {
    const std::size_t n = count(field);
    if (!why_.empty()) return;
    if (n == 0) {
      why_ = std::string(field) + " has length 0 (an LCM string holds at least its NUL)";
      return;
    }
    skip(n, field);
  }
  void strings(std::size_t n, const char* field) {
    for (std::size_t i = 0; i < n && why_.empty(); ++i) string(field);
  }
  /// Empty when the walk consumed exactly the message.
  [[nodiscard]] std::string finish() const {
    if (!why_.empty()) return why_;
    if (pos_ != size_) return std::to_string(size_ - pos_) + " bytes after the message's last field";
    return {};
  }
  [[nodiscard]] bool failed() const { return !why_.empty(); }

 private:
  const std::uint8_t* bytes_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::string why_;
};

constexpr std::size_t kFingerprint = 8;

// The walks follow the .lcm files field by field (common/lcm/*.lcm); the fuzz target checks
// that a walk accepts exactly what decode() decodes.
std::string walk(WireWalk w, const sample_block_t*) {
  w.skip(kFingerprint, "fingerprint");
  w.string("device");
  w.skip(8 + 8 + 8 + 8, "seq, t0_mono_ns, t0_utime, sample_period_s");
  const std::size_t channels = w.count("num_channels");
  w.array(1, channels, 4, "channel_ids");
  w.strings(channels, "channel_names");
  w.strings(channels, "units");
  w.array(1, channels, 8, "channel_seq");
  const std::size_t samples = w.count("num_samples");
  w.array(channels, samples, 8, "values");
  const std::size_t valid_bytes = w.count("valid_bytes");
  w.array(channels, valid_bytes, 1, "valid");
  return w.finish();
}

std::string walk(WireWalk w, const plan_event_t*) {
  w.skip(kFingerprint, "fingerprint");
  w.skip(8 + 8 + 1, "utime, mono_ns, mark");
  w.string("case_name");
  w.string("kind");
  w.string("phase");
  w.skip(4 + 8 + 8, "phase_index, start_mono_ns, end_mono_ns");
  const std::size_t n = w.count("num_setpoints");
  w.strings(n, "setpoint_names");
  w.array(1, n, 8, "setpoint_values");
  w.strings(n, "setpoint_units");
  return w.finish();
}

std::string walk(WireWalk w, const bench_config_t*) {
  w.skip(kFingerprint, "fingerprint");
  w.skip(8, "utime");
  w.string("bench_name");
  const std::size_t n = w.count("num_files");
  w.strings(n, "paths");
  w.strings(n, "texts");
  return w.finish();
}

template <class Message>
std::string decode_checked(const void* data, std::size_t size, Message& message) {
  if (size > static_cast<std::size_t>(std::numeric_limits<int>::max())) return "larger than 2 GiB";
  if (std::string why = walk(WireWalk(data, size), static_cast<const Message*>(nullptr)); !why.empty()) return why;
  const int n = static_cast<int>(size);
  if (message.decode(data, 0, n) != n) return "does not decode (another type: its fingerprint differs)";
  return {};
}

}  // namespace

std::string decode_outside(const void* data, std::size_t size, sample_block_t& message) {
  return decode_checked(data, size, message);
}
std::string decode_outside(const void* data, std::size_t size, plan_event_t& message) {
  return decode_checked(data, size, message);
}
std::string decode_outside(const void* data, std::size_t size, bench_config_t& message) {
  return decode_checked(data, size, message);
}

}  // namespace inertia
