#pragma once
// `inertia-analyze online --config FILE [--model [SENSOR=]MODEL.toml ...] [--duration S]`
// (design.md "Command line"): subscribes to the daemon's stream (INERTIA_BENCH, INERTIA_RAW_*,
// INERTIA_EVENT), fuses the references into ground truth case by case (fusion/stream_assembler),
// runs the recursive ULS per sensor under test (online/online_estimator) and publishes
// model_estimate_t on INERTIA_ESTIMATE_<SENSOR> at --publish-hz, for lcm-spy to tail.
//
// Latency: the references are fused per test case (the shaker's complementary filter and the
// table's attitude need the whole case), so the estimate moves when a case ends; between case ends
// it is re-published unchanged with its sample count, so a subscriber sees it alive.
#include <atomic>
#include <filesystem>
#include <iosfwd>
#include <map>
#include <string>

namespace inertia::commands {

struct OnlineCommandOptions {
  std::filesystem::path config;                           // the bench file the daemon runs
  std::map<std::string, std::filesystem::path> models;    // sensor -> model.toml; key "" = the only sensor
  double duration_s = 0.0;      // > 0: stop after this long; 0: until SIGINT/SIGTERM
  double publish_hz = 2.0;
  double forgetting = 1.0;      // recursive ULS lambda in (0, 1]
  std::string lcm_url;          // empty: $LCM_DEFAULT_URL or LCM's default
  /// Stop request from outside (tests); SIGINT and SIGTERM also stop the loop.
  std::atomic<bool>* stop = nullptr;
};

/// Runs until stopped; prints one line per published estimate change and a summary to `out`.
/// Exit status per design.md: 0, 2 for bad input (bench, model, options), 1 when LCM cannot start.
int run_online(const OnlineCommandOptions& options, std::ostream& out);

}  // namespace inertia::commands
