#include "analyzer/commands/online.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <utility>
#include <csignal>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <optional>
#include <ostream>
#include <vector>

#include "analyzer/fusion/log_dataset.hpp"
#include "analyzer/fusion/stream_assembler.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/online/online_estimator.hpp"
#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"
#include "common/lcm/channels.hpp"
#include "common/lcm/multicast_route.hpp"
#include "inertia/model_estimate_t.hpp"

namespace inertia::commands {
namespace {

volatile std::sig_atomic_t g_signalled = 0;
extern "C" void on_stop_signal(int) { g_signalled = 1; }

std::int64_t wall_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

/// One sensor under test: its own assembler (fusion at the sensor's position) and estimator.
struct SensorPipeline {
  std::string name, output_unit, channel;
  std::unique_ptr<online::OnlineEstimator> estimator;
  std::unique_ptr<fusion::StreamAssembler> assembler;
  std::int64_t newest_mono_ns = 0;
  std::int64_t segments = 0, published = 0, last_printed_samples = -1;
};

dataset::SensorKind sensor_kind(config::SensorType t) {
  return t == config::SensorType::Accelerometer ? dataset::SensorKind::Accelerometer : dataset::SensorKind::Gyroscope;
}

model_estimate_t to_message(const SensorPipeline& p, const online::OnlineSnapshot& s) {
  model_estimate_t m{};
  m.utime = wall_utime();
  m.mono_ns = p.newest_mono_ns;
  m.sensor = p.name;
  m.output_unit = p.output_unit;
  m.num_terms = static_cast<std::int32_t>(s.terms.size());
  m.terms = s.terms;
  m.values.assign(s.values.data(), s.values.data() + s.values.size());
  m.std_devs.assign(s.std_devs.data(), s.std_devs.data() + s.std_devs.size());
  m.residual_variance = s.residual_variance;
  for (int i = 0; i < 3; ++i) m.misalignment_rad[i] = s.misalignment_rad(i);
  m.samples_used = s.samples_used;
  m.converged = s.converged;
  return m;
}

class Subscriber {
 public:
  Subscriber(std::vector<SensorPipeline>& pipelines, std::string expected_bench)
      : pipelines_(pipelines), expected_bench_(std::move(expected_bench)) {}

  // Callbacks run inside lcm_handle (C): an exception must not unwind through it, so bad input
  // is kept and rethrown by rethrow() after handleTimeout returns.
  void on_bench(const lcm::ReceiveBuffer*, const std::string& channel, const bench_config_t* msg) {
    guarded([&] {
      if (msg->bench_name != expected_bench_) {
        throw InputError(fmt::format("{}: the daemon runs bench '{}', --config names bench '{}'", channel,
                                     msg->bench_name, expected_bench_));
      }
      for (SensorPipeline& p : pipelines_) p.assembler->push(*msg, where(channel));
    });
  }
  void on_event(const lcm::ReceiveBuffer*, const std::string& channel, const plan_event_t* msg) {
    guarded([&] {
      for (SensorPipeline& p : pipelines_) p.assembler->push(*msg, where(channel));
    });
  }
  void on_block(const lcm::ReceiveBuffer*, const std::string& channel, const sample_block_t* msg) {
    guarded([&] {
      const auto end_ns = msg->t0_mono_ns + static_cast<std::int64_t>(msg->num_samples * msg->sample_period_s * 1e9);
      for (SensorPipeline& p : pipelines_) {
        p.assembler->push(*msg, where(channel));
        p.newest_mono_ns = std::max(p.newest_mono_ns, end_ns);
      }
    });
  }
  void rethrow() {
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }

 private:
  std::string where(const std::string& channel) { return fmt::format("live message {} on {}", ++messages_, channel); }
  std::vector<SensorPipeline>& pipelines_;
  template <class F>
  void guarded(F&& f) {
    if (error_) return;   // the first error stops the run; later messages are not looked at
    try {
      f();
    } catch (...) {
      error_ = std::current_exception();
    }
  }
  std::string expected_bench_;
  std::int64_t messages_ = 0;
  std::exception_ptr error_;
};

}  // namespace

int run_online(const OnlineCommandOptions& options, std::ostream& out) {
  if (!(options.publish_hz > 0.0) || options.publish_hz > 1000.0)
    throw InputError(fmt::format("online: --publish-hz {} must be in (0, 1000]", options.publish_hz));
  if (!(options.forgetting > 0.0) || options.forgetting > 1.0)
    throw InputError(fmt::format("online: --forgetting {} must be in (0, 1]", options.forgetting));
  if (options.duration_s < 0.0) throw InputError("online: --duration must be >= 0");

  const config::BenchConfig bench = config::load_bench_config(options.config);
  if (bench.sensors.empty()) throw InputError(options.config.string() + ": the bench has no sensor under test");
  for (const auto& [sensor, file] : options.models) {
    if (sensor.empty() && bench.sensors.size() > 1)
      throw InputError("online: the bench has several sensors; give --model SENSOR=FILE");
    bool known = sensor.empty();
    for (const config::SensorUnderTest& s : bench.sensors) known = known || s.name == sensor;
    if (!known) throw InputError("online: --model names sensor '" + sensor + "', which the bench lacks");
  }

  online::OnlineOptions estimator_options;
  estimator_options.uls.forgetting = options.forgetting;
  std::vector<SensorPipeline> pipelines(bench.sensors.size());
  for (std::size_t i = 0; i < bench.sensors.size(); ++i) {
    const config::SensorUnderTest& s = bench.sensors[i];
    SensorPipeline& p = pipelines[i];
    p.name = s.name;
    p.output_unit = s.output_unit;
    p.channel = channels::estimate_channel(s.name);
    std::optional<model::ModelFile> model;
    if (auto it = options.models.find(s.name); it != options.models.end()) model = model::read_model(it->second);
    else if (auto only = options.models.find(""); only != options.models.end()) model = model::read_model(only->second);
    p.estimator = std::make_unique<online::OnlineEstimator>(sensor_kind(s.type), model, bench.t_ref_c, estimator_options);
    fusion::AssemblerOptions ao;
    ao.sensor = s.name;
    p.assembler = std::make_unique<fusion::StreamAssembler>(ao, [&p](fusion::FusedSegment&& seg) {
      const config::TestCase& tc = p.assembler->bench().cases[seg.case_index];
      p.estimator->push(fusion::to_case_data(std::move(seg), tc), false);
      ++p.segments;
    });
  }

  const std::string url = lcm_url(options.lcm_url);
  if (is_udpm(url) && !has_multicast_route()) {
    fmt::print(stderr, "inertia-analyze online: {}\n", kMulticastRouteFix);
    return 1;
  }
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    fmt::print(stderr, "inertia-analyze online: LCM failed to start on '{}'\n", url.empty() ? "default" : url);
    return 1;
  }
  Subscriber subscriber(pipelines, bench.name);
  lcm.subscribe(std::string(channels::kBench), &Subscriber::on_bench, &subscriber);
  lcm.subscribe(std::string(channels::kEvent), &Subscriber::on_event, &subscriber);
  lcm.subscribe(std::string(channels::kRawPrefix) + ".*", &Subscriber::on_block, &subscriber);

  g_signalled = 0;
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  struct sigaction old_int {}, old_term {};
  ::sigaction(SIGINT, &sa, &old_int);
  ::sigaction(SIGTERM, &sa, &old_term);

  fmt::print(out, "online: bench {}, {} sensor(s), publishing {} at {} Hz\n", bench.name, pipelines.size(),
             pipelines.front().channel, options.publish_hz);
  out.flush();
  const auto start = std::chrono::steady_clock::now();
  const auto period = std::chrono::duration<double>(1.0 / options.publish_hz);
  auto next_publish = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
  const auto publish_all = [&] {
    for (SensorPipeline& p : pipelines) {
      const online::OnlineSnapshot s = p.estimator->snapshot();
      const model_estimate_t msg = to_message(p, s);
      lcm.publish(p.channel, &msg);
      ++p.published;
      if (s.samples_used != p.last_printed_samples) {
        p.last_printed_samples = s.samples_used;
        std::string coefficients;
        for (std::size_t j = 0; j < s.terms.size(); ++j)
          coefficients += fmt::format(" {}={:.6g}", s.terms[j], s.values(static_cast<Eigen::Index>(j)));
        fmt::print(out, "{}: {} samples, {}converged,{}\n", p.name, s.samples_used, s.converged ? "" : "not ",
                   coefficients);
        out.flush();
      }
    }
  };

  int status = 0;
  try {
    for (;;) {
      if (g_signalled != 0 || (options.stop != nullptr && options.stop->load())) break;
      const auto now = std::chrono::steady_clock::now();
      if (options.duration_s > 0.0 && now - start >= std::chrono::duration<double>(options.duration_s)) break;
      if (now >= next_publish) {
        publish_all();
        next_publish += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
        if (next_publish < now) next_publish = now;   // a long fusion step: do not publish in a burst
      }
      const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(next_publish - now).count();
      if (lcm.handleTimeout(static_cast<int>(std::clamp<long long>(wait, 1, 100))) < 0 && g_signalled == 0) {
        fmt::print(stderr, "inertia-analyze online: LCM receive failed\n");
        status = 1;
        break;
      }
      subscriber.rethrow();
    }
    // The case in progress, fused with what arrived (a stream that never sent its bench is not an error here).
    for (SensorPipeline& p : pipelines) {
      if (p.assembler->has_bench()) {
        try {
          p.assembler->finish();
        } catch (const InputError& e) {
          fmt::print(out, "{}: {}\n", p.name, e.what());
        }
      }
    }
    publish_all();
  } catch (...) {
    ::sigaction(SIGINT, &old_int, nullptr);
    ::sigaction(SIGTERM, &old_term, nullptr);
    throw;
  }
  ::sigaction(SIGINT, &old_int, nullptr);
  ::sigaction(SIGTERM, &old_term, nullptr);

  for (const SensorPipeline& p : pipelines) {
    fmt::print(out, "online: {}: {} fused segment(s), {} estimate(s) published on {}", p.name, p.segments,
               p.published, p.channel);
    if (p.assembler->has_bench()) {
      fmt::print(out, ", {} fused rows, {} gap(s), {} exclusion(s), {} block(s) before the bench",
                 p.assembler->fused_rows(), p.assembler->gaps().size(), p.assembler->exclusions().size(),
                 p.assembler->skipped_blocks());
    } else {
      fmt::print(out, ", no INERTIA_BENCH received (is inertia-daqd running on this LCM URL?)");
    }
    fmt::print(out, "\n");
  }
  return status;
}

}  // namespace inertia::commands
