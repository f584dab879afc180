#pragma once
// The LCM channel names of docs/design.md ("LCM"), in one place: the daemon publishes them, the
// analyzer subscribes to them and reads them from logs, and scripts outside the code tail them.
#include <string>
#include <string_view>

namespace inertia::channels {

inline constexpr std::string_view kEvent = "INERTIA_EVENT";     // plan_event_t
inline constexpr std::string_view kStatus = "INERTIA_STATUS";   // daq_status_t, 1 Hz
inline constexpr std::string_view kBench = "INERTIA_BENCH";     // bench_config_t (extension, docs/design.md)
/// The daemon sends kBench at start and again every this many seconds, so that a late subscriber
/// (lcm-logger, an analyzer joining a running daemon) gets the bench.
inline constexpr double kBenchResendPeriodS = 10.0;
// Operator requests to the daemon (`inertia-daqd mark`) and its answers: plan_command_t (extension, docs/design.md).
// A request on kCommand carries no identity: refused and counted. From another machine a request
// is signed (signed_command_t on kCommandSigned); on this one it goes through the daemon's command
// socket (daq/command_socket.hpp). Every accepted request is also published on kOperator, and
// so logged, with who sent it.
inline constexpr std::string_view kCommand = "INERTIA_COMMAND";
inline constexpr std::string_view kCommandSigned = "INERTIA_COMMAND_SIGNED";   // signed_command_t
inline constexpr std::string_view kCommandReply = "INERTIA_COMMAND_REPLY";
inline constexpr std::string_view kOperator = "INERTIA_OPERATOR";              // plan_command_t, accepted
inline constexpr std::string_view kRawPrefix = "INERTIA_RAW_";           // + device: sample_block_t
inline constexpr std::string_view kEstimatePrefix = "INERTIA_ESTIMATE_"; // + sensor: model_estimate_t
inline constexpr std::string_view kStructurePrefix = "INERTIA_STRUCTURE_";  // + sensor: structure_table_t (extension)
inline constexpr std::string_view kAnalyzerStatus = "INERTIA_ANALYZER_STATUS";  // analyzer_status_t, 1 Hz (extension)

/// A bench name as a channel suffix: upper case, anything but [A-Z0-9_] becomes '_'
/// ("ref_accel-1" -> "REF_ACCEL_1"), so channel names stay valid LCM regex literals.
inline std::string channel_suffix(std::string_view name) {
  std::string out;
  out.reserve(name.size());
  for (char c : name) {
    const char u = (c >= 'a' && c <= 'z') ? static_cast<char>(c - 'a' + 'A') : c;
    out += ((u >= 'A' && u <= 'Z') || (u >= '0' && u <= '9') || u == '_') ? u : '_';
  }
  return out;
}

inline std::string raw_channel(std::string_view device) { return std::string(kRawPrefix) + channel_suffix(device); }
inline std::string estimate_channel(std::string_view sensor) {
  return std::string(kEstimatePrefix) + channel_suffix(sensor);
}
inline std::string structure_channel(std::string_view sensor) {
  return std::string(kStructurePrefix) + channel_suffix(sensor);
}

}  // namespace inertia::channels
