#include "analyzer/commands/online.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <ostream>
#include <thread>
#include <vector>

#include "analyzer/fusion/stream_assembler.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/online/online_estimator.hpp"
#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"
#include "common/lcm/channels.hpp"
#include "common/lcm/event_log_reader.hpp"
#include "common/lcm/message_decode.hpp"
#include "common/lcm/multicast_route.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "inertia/analyzer_status_t.hpp"
#include "inertia/model_estimate_t.hpp"
#include "inertia/structure_table_t.hpp"

namespace inertia::commands {
namespace {

volatile std::sig_atomic_t g_signalled = 0;
extern "C" void on_stop_signal(int) { g_signalled = 1; }

std::int64_t mono_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
std::int64_t wall_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}
double cpu_seconds() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

/// The largest message a sample block of the daemon can be (one UDP datagram, daq/publisher) with
/// room to spare; anything longer on a RAW channel is not ours.
constexpr std::size_t kMaxRawMessage = 1u << 20;

struct Message {
  std::string channel;
  std::vector<std::uint8_t> data;
  std::int64_t arrival_ns = 0;
};

/// Messages from the LCM thread to the worker: bounded, so a worker that falls behind costs
/// counted messages and never unbounded memory.
class Inbox {
 public:
  explicit Inbox(std::size_t capacity) : capacity_(capacity) {}
  void push(Message&& m) {
    {
      const std::lock_guard lock(mutex_);
      if (queue_.size() >= capacity_) {
        ++drops_;
        return;
      }
      queue_.push_back(std::move(m));
      high_water_ = std::max(high_water_, queue_.size());
    }
    ready_.notify_one();
  }
  /// Waits until something arrives or `until`; returns what is there.
  std::deque<Message> take(std::chrono::steady_clock::time_point until) {
    std::unique_lock lock(mutex_);
    ready_.wait_until(lock, until, [this] { return !queue_.empty() || closed_; });
    std::deque<Message> out;
    out.swap(queue_);
    return out;
  }
  void close() {
    {
      const std::lock_guard lock(mutex_);
      closed_ = true;
    }
    ready_.notify_all();
  }
  [[nodiscard]] bool closed() {
    const std::lock_guard lock(mutex_);
    return closed_;
  }
  std::int64_t drops() {
    const std::lock_guard lock(mutex_);
    return drops_;
  }
  std::size_t high_water() {
    const std::lock_guard lock(mutex_);
    return high_water_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<Message> queue_;
  std::size_t capacity_;
  std::int64_t drops_ = 0;
  std::size_t high_water_ = 0;
  bool closed_ = false;
};

/// Encoded messages from the worker to the LCM thread, which publishes them.
class Outbox {
 public:
  template <class T>
  void push(const std::string& channel, const T& msg) {
    Message m;
    m.channel = channel;
    m.data.resize(static_cast<std::size_t>(msg.getEncodedSize()));
    if (msg.encode(m.data.data(), 0, static_cast<int>(m.data.size())) < 0) return;
    const std::lock_guard lock(mutex_);
    queue_.push_back(std::move(m));
  }
  std::deque<Message> take() {
    const std::lock_guard lock(mutex_);
    std::deque<Message> out;
    out.swap(queue_);
    return out;
  }

 private:
  std::mutex mutex_;
  std::deque<Message> queue_;
};

dataset::SensorKind sensor_kind(config::SensorType t) {
  return t == config::SensorType::Accelerometer ? dataset::SensorKind::Accelerometer : dataset::SensorKind::Gyroscope;
}

struct HistoryRow {
  double t_s = 0.0;   // since the first fused row
  std::int64_t samples = 0;
  Eigen::VectorXd values, std_devs;
  bool converged = false;
};

/// One sensor under test: its assembler (fusion at its position) and estimator.
class SensorPipeline final : public fusion::FusionSink {
 public:
  /// `max_wait_s`: how long (stream time) a late device or marker is waited for (fusion::AssemblerOptions).
  SensorPipeline(const config::SensorUnderTest& s, const std::optional<model::ModelFile>& model, const config::BenchConfig& bench,
                 const online::OnlineOptions& estimator_options, double max_wait_s)
      : name(s.name), output_unit(s.output_unit), estimate_channel(channels::estimate_channel(s.name)),
        structure_channel(channels::structure_channel(s.name)), model_(model), kind_(sensor_kind(s.type)),
        t_ref_(bench.t_ref_c), estimator_options_(estimator_options), max_wait_s_(max_wait_s) {
    estimator_options_.unit_axis = s.unit_axis;
    restart();
  }

  void restart() {
    estimator = std::make_unique<online::OnlineEstimator>(kind_, model_, t_ref_, estimator_options_);
    fusion::AssemblerOptions ao;
    ao.sensor = name;
    ao.min_segment_s = estimator_options_.min_segment_s;
    ao.max_wait_s = max_wait_s_;
    assembler = std::make_unique<fusion::StreamAssembler>(ao, *this);
    newest_mono_ns = 0;
    last_published_newest_ns = 0;
    first_mono_ns = 0;
    rows_fused = 0;
    history.clear();
  }

  void on_rows(fusion::FusedChunk&& chunk) override {
    estimator->push(chunk, assembler->bench().cases[chunk.case_index]);
    newest_mono_ns = std::max(newest_mono_ns, chunk.newest_mono_ns);
    if (first_mono_ns == 0) first_mono_ns = chunk.newest_mono_ns - static_cast<std::int64_t>(1e9 * chunk.sample_period_s * static_cast<double>(chunk.rows() - 1));
    rows_fused += chunk.rows();
  }
  void on_segment_end(const fusion::SegmentEnd& end) override { estimator->end_segment(end); }

  std::string name, output_unit, estimate_channel, structure_channel;
  std::unique_ptr<online::OnlineEstimator> estimator;
  std::unique_ptr<fusion::StreamAssembler> assembler;
  std::int64_t newest_mono_ns = 0, first_mono_ns = 0, rows_fused = 0, rows_estimated = 0, last_published_newest_ns = 0;
  std::int64_t last_printed_samples = -1;
  std::chrono::steady_clock::time_point last_print{};
  std::vector<HistoryRow> history;
  std::optional<double> first_estimate_after_first_block_s;

 private:
  std::optional<model::ModelFile> model_;
  dataset::SensorKind kind_;
  double t_ref_;
  online::OnlineOptions estimator_options_;
  double max_wait_s_;
};

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
  m.t_values.assign(s.t.data(), s.t.data() + s.t.size());
  m.residual_variance = s.residual_variance;
  for (int i = 0; i < 3; ++i)
    m.misalignment_rad[i] = s.mountings.empty() ? std::nan("") : s.mountings.front().angles_rad(i);
  m.samples_used = s.samples_used;
  m.converged = s.converged;
  m.convergence = s.convergence;
  m.cases_used = static_cast<std::int32_t>(s.cases_used);
  m.noise_ar_order = s.noise_order;
  m.square_corner_rad_s = s.corner_rad_s ? *s.corner_rad_s : std::nan("");
  m.num_mountings = static_cast<std::int32_t>(s.mountings.size());
  for (const online::MountingEstimate& e : s.mountings) {
    m.mountings.push_back(e.name);
    m.mounting_determined.push_back(e.determined);
    std::vector<double> a(3), sd(3);
    for (int i = 0; i < 3; ++i) {
      a[static_cast<std::size_t>(i)] = e.angles_rad(i);
      sd[static_cast<std::size_t>(i)] = e.angles_sd_rad(i);
    }
    m.mounting_angles_rad.push_back(a);
    m.mounting_angles_sd_rad.push_back(sd);
    m.mounting_samples.push_back(e.samples);
    m.mounting_notes.push_back(e.note);
  }
  return m;
}

structure_table_t to_structure(const SensorPipeline& p, const online::OnlineSnapshot& s) {
  structure_table_t m{};
  m.utime = wall_utime();
  m.mono_ns = p.newest_mono_ns;
  m.sensor = p.name;
  m.num_candidates = static_cast<std::int32_t>(s.structure.size());
  for (const online::CandidateEstimate& c : s.structure) {
    m.terms.push_back(c.term);
    m.effects.push_back(c.effect);
    m.err.push_back(c.err);
    m.values.push_back(c.value);
    m.std_devs.push_back(c.sd);
    m.t_values.push_back(c.t);
    m.significant.push_back(c.significant);
  }
  return m;
}

/// What the worker counts (it alone writes them).
struct Counters {
  std::int64_t received = 0, malformed = 0, oversized = 0, invalid = 0, refused = 0, invalid_values = 0;
  std::int32_t bench_restarts = 0;
  std::deque<std::string> notes;
  void note(std::string s) {
    notes.push_back(std::move(s));
    while (notes.size() > 16) notes.pop_front();
  }
};

/// The history file's term columns: every sensor's terms, in order of first appearance (sensors of
/// different kinds track different terms; a sensor leaves the others' cells empty).
std::vector<std::string> history_terms(const std::vector<std::unique_ptr<SensorPipeline>>& pipelines) {
  std::vector<std::string> out;
  for (const auto& p : pipelines)
    for (const std::string& t : p->estimator->terms())
      if (std::find(out.begin(), out.end(), t) == out.end()) out.push_back(t);
  return out;
}

class Worker {
 public:
  Worker(std::vector<std::unique_ptr<SensorPipeline>>& pipelines, const config::BenchConfig& bench, Inbox& inbox,
         Outbox& outbox, double publish_hz, std::ostream& out, std::ofstream* history)
      : pipelines_(pipelines), bench_(bench), inbox_(inbox), outbox_(outbox), publish_hz_(publish_hz), out_(out),
        history_(history), history_terms_(history_terms(pipelines)) {}

  void run() {
    const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(1.0 / publish_hz_));
    auto next_publish = std::chrono::steady_clock::now() + period;
    auto next_status = std::chrono::steady_clock::now() + std::chrono::seconds(1);
    status_started_ = std::chrono::steady_clock::now();
    status_cpu_ = cpu_seconds();
    for (;;) {
      const bool closing = inbox_.closed();
      for (Message& m : inbox_.take(std::min(next_publish, next_status))) process(m);
      const auto now = std::chrono::steady_clock::now();
      if (now >= next_publish) {
        publish();
        next_publish += period;
        if (next_publish < now) next_publish = now + period;   // a long step: do not publish in a burst
      }
      if (now >= next_status) {
        status();
        next_status += std::chrono::seconds(1);
        if (next_status < now) next_status = now + std::chrono::seconds(1);
      }
      if (closing) break;
    }
    // The rows still held back (the last samples' differences, an open case): fused and published.
    for (auto& p : pipelines_) {
      if (!p->assembler->has_bench()) continue;
      try {
        p->assembler->finish();
      } catch (const InputError& e) {
        fmt::print(out_, "{}: {}\n", p->name, e.what());
      }
      p->estimator->end_of_stream();
    }
    publish();
    status();
  }

  /// One message, as the worker thread takes it (a replayed log).
  void ingest(const Message& m) {
    replay_now_ns_ = m.arrival_ns;   // a replay runs on the log's clock, which stamped the arrivals
    process(m);
  }
  void publish_now() { publish(); }
  /// The end of a replayed log: the rows held back, fused; a noise window the log did not fill,
  /// fitted on its rows; one estimate per sensor published.
  void finish_replay() {
    for (auto& p : pipelines_) {
      if (!p->assembler->has_bench()) continue;
      try {
        p->assembler->finish();
      } catch (const InputError& e) {
        fmt::print(out_, "{}: {}\n", p->name, e.what());
      }
      p->estimator->end_of_stream();
    }
    publish();
  }

  [[nodiscard]] const Counters& counters() const { return counters_; }
  [[nodiscard]] std::int64_t first_block_ns() const { return first_block_ns_; }

 private:
  template <class T>
  bool decode(const Message& m, T& msg) {
    // decode_outside: lcm-gen's own decode() allocates whatever counts a hostile message claims.
    if (const std::string why = decode_outside(m.data.data(), m.data.size(), msg); !why.empty()) {
      ++counters_.malformed;
      if (counters_.malformed <= 3) counters_.note(fmt::format("{}: message does not decode: {}", m.channel, why));
      return false;
    }
    return true;
  }

  template <class F>
  void each_pipeline(const std::string& channel, F&& f) {
    for (auto& p : pipelines_) {
      try {
        f(*p);
      } catch (const InputError& e) {
        ++counters_.refused;
        counters_.note(fmt::format("{}: {}: {}", p->name, channel, e.what()));
      }
    }
  }

  void process(const Message& m) {
    ++counters_.received;
    const std::string where = fmt::format("live message {} on {}", counters_.received, m.channel);
    if (m.channel == channels::kBench) {
      bench_config_t b;
      if (!decode(m, b)) return;
      if (b.bench_name != bench_.name) {
        ++counters_.refused;
        counters_.note(fmt::format("{}: the daemon runs bench '{}', --config names bench '{}'", m.channel, b.bench_name, bench_.name));
        return;
      }
      std::vector<std::string> texts(b.texts.begin(), b.texts.end());
      if (!bench_texts_.empty() && texts != bench_texts_) {
        // The bench file changed under a running test: what came before was another bench.
        ++counters_.bench_restarts;
        counters_.note("INERTIA_BENCH changed: estimation restarted");
        fmt::print(out_, "online: the daemon's bench file changed: estimation restarted\n");
        for (auto& p : pipelines_) p->restart();
      }
      bench_texts_ = std::move(texts);
      each_pipeline(m.channel, [&](SensorPipeline& p) { p.assembler->push(b, where); });
    } else if (m.channel == channels::kEvent) {
      plan_event_t e;
      if (!decode(m, e)) return;
      each_pipeline(m.channel, [&](SensorPipeline& p) { p.assembler->push(e, where); });
    } else if (m.channel.rfind(channels::kRawPrefix, 0) == 0) {
      if (m.data.size() > kMaxRawMessage) {
        ++counters_.oversized;
        return;
      }
      sample_block_t b;
      if (!decode(m, b)) return;
      if (const std::string why = block_shape_error(b); !why.empty()) {
        ++counters_.invalid;
        counters_.note(fmt::format("{}: {}", m.channel, why));
        return;
      }
      for (std::int32_t c = 0; c < b.num_channels; ++c)
        for (std::int32_t s = 0; s < b.num_samples; ++s)
          if (sample_valid(b, c, s) && !std::isfinite(b.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)]))
            ++counters_.invalid_values;   // the fusion takes them as invalid
      if (first_block_ns_ == 0) first_block_ns_ = m.arrival_ns;
      each_pipeline(m.channel, [&](SensorPipeline& p) { p.assembler->push(b, where); });
    }
  }

  void publish() {
    const std::int64_t now = replay_now_ns_.value_or(mono_ns());
    for (auto& p : pipelines_) {
      const online::OnlineSnapshot s = p->estimator->snapshot();
      p->rows_estimated = s.samples_used;
      outbox_.push(p->estimate_channel, to_message(*p, s));
      outbox_.push(p->structure_channel, to_structure(*p, s));
      // Latency of the estimates that carry new samples (an idle stream is not late).
      if (s.samples_used > 0 && p->newest_mono_ns > p->last_published_newest_ns) {
        latencies_.push_back(1e-6 * static_cast<double>(now - p->newest_mono_ns));
        p->last_published_newest_ns = p->newest_mono_ns;
      }
      if (s.samples_used > 0 && !p->first_estimate_after_first_block_s && first_block_ns_ > 0)
        p->first_estimate_after_first_block_s = 1e-9 * static_cast<double>(now - first_block_ns_);
      if (s.samples_used > 0 && p->first_mono_ns > 0) {
        const double t = 1e-9 * static_cast<double>(p->newest_mono_ns - p->first_mono_ns);
        p->history.push_back({t, s.samples_used, s.values, s.std_devs, s.converged});
        if (history_ != nullptr) {
          *history_ << fmt::format("{},{:.4f},{},{},{}", p->name, t, s.samples_used, s.cases_used, s.converged ? 1 : 0);
          for (const std::string& term : history_terms_) {
            const auto j = std::find(s.terms.begin(), s.terms.end(), term) - s.terms.begin();
            if (j == static_cast<std::ptrdiff_t>(s.terms.size())) *history_ << ",,";
            else *history_ << fmt::format(",{:.9g},{:.3g}", s.values(j), s.std_devs(j));
          }
          *history_ << '\n';
        }
      }
      const auto wall = std::chrono::steady_clock::now();
      if (s.samples_used != p->last_printed_samples && wall - p->last_print >= std::chrono::seconds(1)) {
        p->last_printed_samples = s.samples_used;
        p->last_print = wall;
        std::string coefficients;
        for (std::size_t j = 0; j < s.terms.size() && j < 4; ++j)
          coefficients += fmt::format(" {}={:.6g}", s.terms[j], s.values(static_cast<Eigen::Index>(j)));
        fmt::print(out_, "{}: {} samples in {} case(s), {}converged,{}{}\n", p->name, s.samples_used, s.cases_used,
                   s.converged ? "" : "not ", coefficients, s.terms.size() > 4 ? " ..." : "");
        out_.flush();
      }
    }
  }

  void status() {
    const auto now = std::chrono::steady_clock::now();
    const double cpu = cpu_seconds();
    const double dt = std::chrono::duration<double>(now - status_started_).count();
    analyzer_status_t st{};
    st.utime = wall_utime();
    st.mono_ns = mono_ns();
    st.uptime_s = std::chrono::duration<double>(now - started_).count();
    st.bench = bench_texts_.empty() ? "" : bench_.name;
    st.bench_restarts = counters_.bench_restarts;
    st.received = counters_.received;
    st.skipped_malformed = counters_.malformed;
    st.skipped_oversized = counters_.oversized;
    st.skipped_invalid = counters_.invalid;
    st.skipped_refused = counters_.refused;
    st.invalid_values = counters_.invalid_values;
    st.queue_drops = inbox_.drops();
    st.queue_high_water = static_cast<std::int32_t>(inbox_.high_water());
    st.cpu_percent = dt > 0.0 ? 100.0 * (cpu - status_cpu_) / dt : 0.0;
    if (!latencies_.empty()) {
      std::sort(latencies_.begin(), latencies_.end());
      const auto at = [&](double q) { return latencies_[static_cast<std::size_t>(q * static_cast<double>(latencies_.size() - 1))]; };
      st.latency_p50_ms = at(0.5);
      st.latency_p99_ms = at(0.99);
      st.latency_max_ms = latencies_.back();
      all_latencies_.insert(all_latencies_.end(), latencies_.begin(), latencies_.end());
      latencies_.clear();
    }
    std::int64_t gaps = 0;
    for (auto& p : pipelines_) {
      gaps += static_cast<std::int64_t>(p->assembler->gaps().size());
      st.sensors.push_back(p->name);
      st.rows_fused.push_back(p->rows_fused);
      st.rows_estimated.push_back(p->rows_estimated);
      st.exclusions.push_back(static_cast<std::int64_t>(p->assembler->exclusions().size()));
    }
    st.gaps = gaps;
    st.num_sensors = static_cast<std::int32_t>(st.sensors.size());
    st.notes.assign(counters_.notes.begin(), counters_.notes.end());
    st.num_notes = static_cast<std::int32_t>(st.notes.size());
    outbox_.push(std::string(channels::kAnalyzerStatus), st);
    status_started_ = now;
    status_cpu_ = cpu;
    cpu_history_.push_back(st.cpu_percent);
  }

 public:
  std::vector<double> all_latencies_;
  std::vector<double> cpu_history_;

 private:
  std::vector<std::unique_ptr<SensorPipeline>>& pipelines_;
  const config::BenchConfig& bench_;
  Inbox& inbox_;
  Outbox& outbox_;
  double publish_hz_;
  std::ostream& out_;
  std::ofstream* history_;
  std::vector<std::string> history_terms_;   // the history file's term columns (history_terms)
  Counters counters_;
  std::vector<std::string> bench_texts_;
  std::int64_t first_block_ns_ = 0;
  std::optional<std::int64_t> replay_now_ns_;   // a replay: the log time of the newest message
  std::vector<double> latencies_;
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point status_started_;
  double status_cpu_ = 0.0;
};

/// The main thread's side of LCM: every subscribed message goes to the inbox as bytes.
class Receiver {
 public:
  explicit Receiver(Inbox& inbox) : inbox_(inbox) {}
  void on_message(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    Message m;
    m.channel = channel;
    const auto* bytes = static_cast<const std::uint8_t*>(rbuf->data);
    m.data.assign(bytes, bytes + rbuf->data_size);
    m.arrival_ns = mono_ns();
    inbox_.push(std::move(m));
  }

 private:
  Inbox& inbox_;
};

/// The URL with a receive buffer large enough for a burst of sample blocks (the default 208 KiB
/// holds about three), unless the user set one.
std::string with_receive_buffer(const std::string& url) {
  if (!is_udpm(url) || url.find("recv_buf_size") != std::string::npos) return url;
  const std::string base = url.empty() ? "udpm://239.255.76.67:7667?ttl=0" : url;
  return base + (base.find('?') == std::string::npos ? "?" : "&") + "recv_buf_size=4194304";
}

/// When each coefficient settled: the first publish after which every estimate stayed within
/// 3 of its own sd of the final value.
/// The live answer beside a characterization's (model.toml with [std]): per common term both
/// values and z = difference / combined sd.
void print_comparison(const online::OnlineSnapshot& last, const std::filesystem::path& file, std::ostream& out) {
  model::ModelFile offline;
  try {
    offline = model::read_model(file);
  } catch (const InputError& e) {
    fmt::print(out, "  (no comparison: {})\n", e.what());
    return;
  }
  fmt::print(out, "  live beside {} (z = difference / combined sd):\n", file.string());
  fmt::print(out, "  {:<14} {:>16} {:>10} {:>16} {:>10} {:>7}\n", "term", "live", "sd", "offline", "sd", "z");
  for (std::size_t j = 0; j < last.terms.size(); ++j) {
    const auto jj = static_cast<Eigen::Index>(j);
    const ident::Term term = ident::parse_term(last.terms[j]);
    const auto it = std::find_if(offline.terms.begin(), offline.terms.end(), [&](const model::ModelTerm& t) { return t.term == term; });
    if (it == offline.terms.end()) {
      fmt::print(out, "  {:<14} {:>16.9g} {:>10.3g} {:>16} {:>10} {:>7}\n", last.terms[j], last.values(jj), last.std_devs(jj), "-", "-", "-");
      continue;
    }
    const double sd = it->std.value_or(std::nan(""));
    const double z = (last.values(jj) - it->coefficient) / std::hypot(last.std_devs(jj), sd);
    fmt::print(out, "  {:<14} {:>16.9g} {:>10.3g} {:>16.9g} {:>10.3g} {:>+7.2f}\n", last.terms[j], last.values(jj),
               last.std_devs(jj), it->coefficient, sd, z);
  }
}

/// What the fusion made of one sensor's stream: its rows, gaps, exclusions, and a missing bench.
/// Printed the same after a live run and a replay, so the two can be compared.
void print_stream_summary(const SensorPipeline& p, std::ostream& out) {
  fmt::print(out, "online: {}: {} fused rows, {} gap(s), {} exclusion(s), {} block(s) before the bench\n", p.name, p.rows_fused,
             p.assembler->gaps().size(), p.assembler->exclusions().size(), p.assembler->skipped_blocks());
  for (const fusion::StreamGap& g : p.assembler->gaps()) fmt::print(out, "online: {}: gap: {}\n", p.name, describe(g));
  if (!p.assembler->has_bench()) {
    fmt::print(out, "online: {}: no INERTIA_BENCH received (is inertia-daqd running on this LCM URL?)\n", p.name);
  } else if (p.assembler->skipped_blocks() > 0) {
    // The daemon sends its bench file at start and periodically, and a marker at each case's
    // start: an analyzer that joins a running daemon waits for both.
    fmt::print(out,
               "online: {}: joined a running inertia-daqd: its samples are estimated from the first case that started after "
               "its bench file arrived ({}, sent every {:g} s)\n",
               p.name, channels::kBench, channels::kBenchResendPeriodS);
  }
}

void print_settling(const SensorPipeline& p, const online::OnlineSnapshot& last, std::ostream& out) {
  if (p.history.empty()) return;
  fmt::print(out, "online: {}: live estimate history ({} estimates with samples; times from the first fused sample)\n",
             p.name, p.history.size());
  if (p.first_estimate_after_first_block_s)
    fmt::print(out, "  first estimate with samples {:.2f} s after the first raw block arrived\n", *p.first_estimate_after_first_block_s);
  std::optional<double> converged_at;
  for (std::size_t i = 0; i < p.history.size(); ++i) {
    bool stays = true;
    for (std::size_t k = i; k < p.history.size() && stays; ++k) stays = p.history[k].converged;
    if (stays) {
      converged_at = p.history[i].t_s;
      break;
    }
  }
  fmt::print(out, "  {:<14} {:>16} {:>12} {:>12}\n", "term", "final value", "sd", "settled at s");
  for (std::size_t j = 0; j < last.terms.size(); ++j) {
    const auto jj = static_cast<Eigen::Index>(j);
    const double final_value = last.values(jj);
    std::optional<double> settled;
    for (std::size_t i = 0; i < p.history.size() && std::isfinite(final_value); ++i) {
      bool ok = true;
      for (std::size_t k = i; k < p.history.size() && ok; ++k) {
        const HistoryRow& h = p.history[k];
        ok = std::isfinite(h.values(jj)) && std::abs(h.values(jj) - final_value) <= 3.0 * h.std_devs(jj);
      }
      if (ok) {
        settled = p.history[i].t_s;
        break;
      }
    }
    fmt::print(out, "  {:<14} {:>16.9g} {:>12.3g} {:>12}\n", last.terms[j], final_value, last.std_devs(jj),
               settled ? fmt::format("{:.2f}", *settled) : std::string("-"));
  }
  fmt::print(out, "  converged: {}{}\n", last.converged ? "yes" : "no",
             converged_at ? fmt::format(" (from {:.2f} s on)", *converged_at) : std::string());
  fmt::print(out, "  {}\n", last.convergence);
  fmt::print(out, "  noise model AR({}){}{}; squares' corner {}\n", last.noise_order, last.noise_model_fitted ? "" : " (not fitted yet)",
             last.long_run_variance_factor > 1.0
                 ? fmt::format(" (rows kept white for ULS's output-multiplied terms; variances x{:.3g}, the residual's long-run "
                               "power)",
                               last.long_run_variance_factor)
                 : std::string(),
             last.corner_rad_s ? fmt::format("{:.1f} rad/s", *last.corner_rad_s) : std::string("none (static squares)"));
  for (const online::MountingEstimate& m : last.mountings) {
    const auto deg = [](double r) { return r * 180.0 / 3.14159265358979323846; };
    // About i: the twist against the reference mounting, when the data determined it.
    const std::string about_i = std::isfinite(m.angles_rad(0))
                                    ? fmt::format("about i {:+.4f} +- {:.4f} deg against the reference mounting, ",
                                                  deg(m.angles_rad(0)), deg(m.angles_sd_rad(0)))
                                    : std::string();
    fmt::print(out, "  mounting {}: {}, {}about p {:+.5f} +- {:.5f} deg, about o {:+.5f} +- {:.5f} deg{}\n", m.name,
               m.determined ? "determined" : "not determined", about_i, deg(m.angles_rad(1)), deg(m.angles_sd_rad(1)),
               deg(m.angles_rad(2)), deg(m.angles_sd_rad(2)), m.note.empty() ? "" : " (" + m.note + ")");
  }
}

}  // namespace

int run_online(const OnlineCommandOptions& options, std::ostream& out) {
  if (!(options.publish_hz > 0.0) || options.publish_hz > 1000.0)
    throw InputError(fmt::format("online: --publish-hz {} must be in (0, 1000]", options.publish_hz));
  if (!(options.forgetting > 0.0) || options.forgetting > 1.0)
    throw InputError(fmt::format("online: --forgetting {} must be in (0, 1]", options.forgetting));
  if (!(options.duration_s >= 0.0)) throw InputError("online: --duration must be >= 0");
  if (!(options.noise_window_s >= 0.0)) throw InputError("online: --noise-window must be >= 0");

  const config::BenchConfig bench = config::load_bench_config(options.config);
  if (bench.sensors.empty()) throw InputError(options.config.string() + ": the bench has no sensor under test");
  for (const auto& [sensor, file] : options.models) {
    if (sensor.empty() && bench.sensors.size() > 1)
      throw InputError("online: the bench has several sensors; give --model SENSOR=FILE");
    bool known = sensor.empty();
    for (const config::SensorUnderTest& s : bench.sensors) known = known || s.name == sensor;
    if (!known) throw InputError("online: --model names sensor '" + sensor + "', which the bench lacks");
  }
  for (const auto& [sensor, file] : options.compare) {
    if (sensor.empty() && bench.sensors.size() > 1)
      throw InputError("online: the bench has several sensors; give --compare SENSOR=FILE");
    if (!sensor.empty() && std::none_of(bench.sensors.begin(), bench.sensors.end(),
                                        [&](const config::SensorUnderTest& s) { return s.name == sensor; }))
      throw InputError("online: --compare names sensor '" + sensor + "', which the bench lacks");
  }
  // The model file a sensor's live answer is compared with, if any.
  const auto compare_file = [&options](const std::string& sensor) -> const std::filesystem::path* {
    if (auto it = options.compare.find(sensor); it != options.compare.end()) return &it->second;
    if (auto only = options.compare.find(""); only != options.compare.end()) return &only->second;
    return nullptr;
  };

  online::OnlineOptions estimator_options;
  estimator_options.forgetting = options.forgetting;
  estimator_options.noise_window_s = options.noise_window_s;
  estimator_options.nominal_sample_period_s = 1.0 / bench.sample_rate_hz;
  estimator_options.temperature_candidates =
      std::any_of(bench.cases.begin(), bench.cases.end(), [](const config::TestCase& c) { return c.varies_temperature(); });
  for (const config::TestCase& c : bench.cases) estimator_options.plan.push_back({c.name, c.mounting, c.kind});
  std::vector<std::unique_ptr<SensorPipeline>> pipelines;
  for (const config::SensorUnderTest& s : bench.sensors) {
    std::optional<model::ModelFile> model;
    if (auto it = options.models.find(s.name); it != options.models.end()) model = model::read_model(it->second);
    else if (auto only = options.models.find(""); only != options.models.end()) model = model::read_model(only->second);
    // Live, a late or silent device or marker is waited for 0.5 s of stream time, so a silent one
    // never stalls the estimate. A replay has the whole log: it waits as characterize --log does.
    // (A --fast run's markers trail its samples by more than 0.5 s of its stream time: given up on,
    // a case's rows went to the case before it.)
    const double max_wait_s = options.replay.empty() ? 0.5 : std::numeric_limits<double>::infinity();
    pipelines.push_back(std::make_unique<SensorPipeline>(s, model, bench, estimator_options, max_wait_s));
  }
  std::optional<std::ofstream> history;
  if (!options.history.empty()) {
    history.emplace(options.history);
    if (!*history) throw InputError(options.history.string() + ": cannot write the history file");
    *history << "sensor,t_s,samples,cases,converged";
    for (const std::string& t : history_terms(pipelines)) *history << ',' << t << ',' << t << "_sd";
    *history << '\n';
  }

  if (!options.replay.empty()) {
    // The same worker on a recorded log, as fast as it reads: the live answer for that log.
    EventLogReader log(options.replay);
    Inbox unused(1);
    Outbox outbox;
    Worker worker(pipelines, bench, unused, outbox, options.publish_hz, out, history ? &*history : nullptr);
    std::int64_t next_publish_us = 0;
    LogRecord record;
    while (log.next(record)) {
      Message m;
      m.channel = std::move(record.channel);
      m.data = std::move(record.data);
      m.arrival_ns = 1000 * record.utime;
      worker.ingest(m);
      // Estimates at the publishing rate, in the log's own time (as the live run would have).
      if (record.utime >= next_publish_us) {
        if (next_publish_us > 0) worker.publish_now();
        next_publish_us = record.utime + static_cast<std::int64_t>(1e6 / options.publish_hz);
        (void)outbox.take();
      }
    }
    if (!log.stop_reason().empty())
      fmt::print(out, "{}: {} (of {} bytes): read up to it\n", options.replay.string(), log.stop_reason(), log.size());
    worker.finish_replay();
    for (const auto& p : pipelines) {
      print_stream_summary(*p, out);
      const online::OnlineSnapshot last = p->estimator->snapshot();
      print_settling(*p, last, out);
      if (const auto* file = compare_file(p->name)) print_comparison(last, *file, out);
    }
    return 0;
  }

  const std::string url = with_receive_buffer(lcm_url(options.lcm_url));
  if (is_udpm(url) && !has_multicast_route()) {
    fmt::print(stderr, "inertia-analyze online: {}\n", kMulticastRouteFix);
    return 1;
  }
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    fmt::print(stderr, "inertia-analyze online: LCM failed to start on '{}'\n", url);
    return 1;
  }
  Inbox inbox(1u << 16);
  Outbox outbox;
  Receiver receiver(inbox);
  for (const std::string& channel : {std::string(channels::kBench), std::string(channels::kEvent),
                                    std::string(channels::kRawPrefix) + ".*"}) {
    lcm::Subscription* sub = lcm.subscribe(channel, &Receiver::on_message, &receiver);
    sub->setQueueCapacity(10000);
  }

  g_signalled = 0;
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  struct sigaction old_int {}, old_term {};
  ::sigaction(SIGINT, &sa, &old_int);
  ::sigaction(SIGTERM, &sa, &old_term);

  fmt::print(out, "online: bench {}, {} sensor(s), publishing {} (and structure, status) at {} Hz\n", bench.name,
             pipelines.size(), pipelines.front()->estimate_channel, options.publish_hz);
  out.flush();
  Worker worker(pipelines, bench, inbox, outbox, options.publish_hz, out, history ? &*history : nullptr);
  std::exception_ptr worker_error;
  std::thread thread([&] {
    try {
      worker.run();
    } catch (...) {
      worker_error = std::current_exception();
    }
  });
  const auto start = std::chrono::steady_clock::now();
  int status = 0;
  const auto flush_outbox = [&] {
    for (Message& m : outbox.take()) lcm.publish(m.channel, m.data.data(), static_cast<unsigned int>(m.data.size()));
  };
  for (;;) {
    if (g_signalled != 0 || (options.stop != nullptr && options.stop->load())) break;
    if (options.duration_s > 0.0 && std::chrono::steady_clock::now() - start >= std::chrono::duration<double>(options.duration_s)) break;
    if (worker_error) break;
    if (lcm.handleTimeout(5) < 0 && g_signalled == 0) {
      fmt::print(stderr, "inertia-analyze online: LCM receive failed\n");
      status = 1;
      break;
    }
    flush_outbox();
  }
  // What is already received is still fused and estimated, then published once more.
  while (lcm.handleTimeout(0) > 0) {
  }
  inbox.close();
  thread.join();
  flush_outbox();
  ::sigaction(SIGINT, &old_int, nullptr);
  ::sigaction(SIGTERM, &old_term, nullptr);
  if (worker_error) std::rethrow_exception(worker_error);

  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fmt::print(out, "online: CPU {:.2f} s over {:.2f} s ({:.1f} % of one core)\n", cpu_seconds(), wall, 100.0 * cpu_seconds() / wall);
  const Counters& c = worker.counters();
  fmt::print(out, "online: received {} message(s); skipped {} malformed, {} oversized, {} invalid, {} refused; {} queue drop(s); {} NaN value(s) taken as invalid\n",
             c.received, c.malformed, c.oversized, c.invalid, c.refused, inbox.drops(), c.invalid_values);
  if (!worker.all_latencies_.empty()) {
    std::vector<double> l = worker.all_latencies_;
    std::sort(l.begin(), l.end());
    if (l.front() < 0.0) {
      // A sample time ahead of this host's clock is no arrival time: the daemon ran a simulated
      // bench faster than real time (--fast), whose samples carry the simulated clock.
      fmt::print(out, "online: sample-to-estimate latency not measured: samples' times ran up to {:.1f} s ahead of this host's "
                      "clock (a simulated bench run with --fast carries the simulated clock)\n",
                 -1e-3 * l.front());
    } else {
      fmt::print(out, "online: sample-to-estimate latency p50 {:.1f} ms, p99 {:.1f} ms, max {:.1f} ms over {} estimate(s)\n",
                 l[l.size() / 2], l[static_cast<std::size_t>(0.99 * static_cast<double>(l.size() - 1))], l.back(), l.size());
    }
  }
  for (const auto& p : pipelines) {
    print_stream_summary(*p, out);
    const online::OnlineSnapshot last = p->estimator->snapshot();
    print_settling(*p, last, out);
    if (const auto* file = compare_file(p->name)) print_comparison(last, *file, out);
  }
  return status;
}

}  // namespace inertia::commands
