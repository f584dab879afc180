#pragma once
// A reference channel of the bench: "<device>.<signal>" as the bench file names it, or the
// simulator's device and signal when the file leaves it out. Shared by the stream assembler and
// the log segmenter, which read the same channels.
#include <string>

namespace inertia::fusion {

struct ChannelRef {
  std::string device;
  std::string signal;
  [[nodiscard]] std::string label() const { return device + "." + signal; }
};

/// `configured` ("device.signal", or "device" for the simulator's signal name), else the
/// simulator's names.
inline ChannelRef channel_of(const std::string& configured, const std::string& sim_device, const std::string& sim_signal) {
  if (configured.empty()) return {sim_device, sim_signal};
  const auto dot = configured.find('.');
  if (dot == std::string::npos) return {configured, sim_signal};
  return {configured.substr(0, dot), configured.substr(dot + 1)};
}

}  // namespace inertia::fusion
