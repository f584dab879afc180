#pragma once
// `inertia-analyze online --config FILE [--model [SENSOR=]MODEL.toml ...] [--duration S]`
// (docs/design.md "Command line"): subscribes to the daemon's stream (INERTIA_BENCH, INERTIA_RAW_*,
// INERTIA_EVENT), fuses the references into ground truth as the samples arrive
// (fusion/stream_assembler: a few samples behind the stream), runs the live estimator per sensor
// under test (online/online_estimator) and publishes, at --publish-hz:
//   INERTIA_ESTIMATE_<SENSOR>   model_estimate_t (terms, sd, t, misalignment per mounting, converged)
//   INERTIA_STRUCTURE_<SENSOR>  structure_table_t (ERR and t of every candidate the model lacks)
//   INERTIA_ANALYZER_STATUS     analyzer_status_t at 1 Hz (received, refused by kind, gaps, CPU, latency)
//
// Threads: the main thread runs LCM (receives into a bounded queue, publishes what the worker
// produced); the worker decodes, fuses and estimates. So a slow step never stalls the socket.
// Bad messages (undecodable, wrong fingerprint, oversized, malformed, NaN times, out of order)
// are counted and skipped, never fatal. A different INERTIA_BENCH restarts the estimation; the
// same bench again (a daemon restart) continues it: its cases add to theirs.
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
  double publish_hz = 10.0;
  double forgetting = 1.0;      // lambda in (0, 1]
  double noise_window_s = 2.0;  // rows that fit the noise model
  std::string lcm_url;          // empty: $LCM_DEFAULT_URL or LCM's default (with a 4 MiB receive buffer)
  std::filesystem::path history;   // non-empty: every published estimate as CSV rows
  std::filesystem::path replay;    // non-empty: run on this event log instead of LCM (no publishing)
  /// At the end, a sensor's live answer beside this model file's (sensor -> file; key "" = the only sensor).
  std::map<std::string, std::filesystem::path> compare;
  /// Stop request from outside (tests); SIGINT and SIGTERM also stop the loop.
  std::atomic<bool>* stop = nullptr;
};

/// Runs until stopped; prints a line per estimate whose sample count changed (at most one a
/// second) and, at the end, when each coefficient settled. Exit status per docs/design.md: 0, 2 for
/// bad input (bench, model, options), 1 when LCM cannot start.
int run_online(const OnlineCommandOptions& options, std::ostream& out);

}  // namespace inertia::commands
