#include "analyzer/fusion/log_segmenter.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "analyzer/fusion/channel_ref.hpp"
#include "common/config/phase_label.hpp"
#include "common/input_error.hpp"
#include "common/lcm/sample_block_layout.hpp"

namespace inertia::fusion {
namespace {

// The floor of the monitors' window sd: this percentile of the log's windows (a bench spends
// more than a tenth of a test at rest), and how far above it vibration stands.
constexpr double kFloorPercentile = 0.10;
constexpr double kVibrationOverFloor = 10.0;
// How far (in -2 log-likelihood) a split between rest and vibration may lie from the best one and
// still be where the change happened: 9, a 3 sd interval were the statistic chi-square with one
// degree of freedom.
constexpr double kEdgeLikelihoodRatio = 9.0;
// Samples left out either side of a cut between two cases (see segment_plan).
constexpr double kCaseGuardSamples = 10.0;

MotionClass class_of(config::PhaseKind kind) {
  switch (kind) {
    case config::PhaseKind::Rotation: return MotionClass::Rotation;
    case config::PhaseKind::Sine:
    case config::PhaseKind::Random:
    case config::PhaseKind::Shock: return MotionClass::Vibration;
    case config::PhaseKind::Dwell:
    case config::PhaseKind::ThermalStep: return MotionClass::Static;
  }
  return MotionClass::Static;
}

std::string sequence(const std::vector<MotionClass>& classes) {
  std::string s;
  for (MotionClass c : classes) s += (s.empty() ? "" : ", ") + std::string(to_string(c));
  return s;
}

}  // namespace

const char* to_string(MotionClass c) {
  switch (c) {
    case MotionClass::Static: return "static";
    case MotionClass::Rotation: return "rotation";
    case MotionClass::Vibration: return "vibration";
  }
  return "?";
}

void LineSums::add(double t_s, double value) {
  n += 1;
  t += t_s;
  tt += t_s * t_s;
  y += value;
  ty += t_s * value;
  yy += value * value;
}

LineSums LineSums::operator-(const LineSums& earlier) const {
  return {n - earlier.n, t - earlier.t, tt - earlier.tt, y - earlier.y, ty - earlier.ty, yy - earlier.yy};
}

double LineSums::residual_ss() const {
  if (n < 3) return 0.0;
  const double stt = tt - t * t / n, sty = ty - t * y / n, syy = yy - y * y / n;
  return std::max(0.0, stt > 0 ? syy - sty * sty / stt : syy);
}

double LineSums::detrended_sd() const { return n < 3 ? 0.0 : std::sqrt(residual_ss() / (n - 2)); }

MotionClassifier::Window::Window()
    : move_first_ns(std::numeric_limits<double>::quiet_NaN()), move_last_ns(std::numeric_limits<double>::quiet_NaN()) {}

MotionClassifier::MotionClassifier(const config::BenchConfig& bench) {
  double window_s = kSegmentWindowS;
  for (const config::TestCase& c : bench.cases)
    for (const config::Phase& p : c.phases) window_s = std::min(window_s, 0.25 * p.duration_s);
  window_ns_ = std::max(window_s, kMinWindowSamples / bench.sample_rate_hz) * 1e9;
  if (bench.table_encoder.present) {
    const ChannelRef r = channel_of(bench.table_encoder.channel, "table_encoder", "position");
    table_device_ = r.device;
    table_signal_ = r.signal;
    move_threshold_ = kMoveCounts * (bench.table_encoder.resolution > 0.0 ? bench.table_encoder.resolution : 1e-6);
  }
  for (const config::MonitorAccelerometer& m : bench.monitors) {
    const ChannelRef r = channel_of(m.channel, "accel", m.name);
    monitor_refs_.emplace_back(r.device, r.signal);
  }
}

void MotionClassifier::push(const sample_block_t& block) {
  // A block the assembler would refuse (sample_block_layout.hpp) is no motion either: its times
  // could lie anywhere (fuzz_event_log met one whose window index overflowed int64).
  if (block.num_samples <= 0 || !block_shape_error(block).empty()) return;
  const double period_ns = block.sample_period_s * 1e9;
  for (std::int32_t c = 0; c < block.num_channels; ++c) {
    const std::string& name = block.channel_names[static_cast<std::size_t>(c)];
    const bool table = block.device == table_device_ && name == table_signal_;
    const std::optional<std::size_t> monitor = monitor_of(block.device, name);
    if (!table && !monitor) continue;
    for (std::int32_t s = 0; s < block.num_samples; ++s) {
      const double v = block.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)];
      if (!sample_valid(block, c, s) || !std::isfinite(v)) continue;
      const double t = static_cast<double>(block.t0_mono_ns) + period_ns * s;
      const auto w = static_cast<std::int64_t>(std::floor(t / window_ns_));
      Window& win = windows_[w];
      const double tw = (t - static_cast<double>(w) * window_ns_) * 1e-9;
      if (table) {
        if (!win.turned_known || tw < win.first_t) {
          win.first_t = tw;
          win.first_angle = v;
        }
        if (!win.turned_known || tw > win.last_t) {
          win.last_t = tw;
          win.last_angle = v;
        }
        win.turned_known = true;
        // The table's blocks come in time order: a streaming record of where it moved.
        // The move starts at the sample before the first one away: the last at rest (a rate
        // step turns the table a whole rate x period by the next sample).
        if (std::isnan(win.move_first_ns) && std::abs(v - win.first_angle) > move_threshold_) win.move_first_ns = t - period_ns;
        if (!anchor_.known || std::abs(v - anchor_.angle) > move_threshold_) {
          if (anchor_.known) win.move_last_ns = t;
          anchor_ = {true, v};
        }
      } else {
        if (win.monitors.size() < monitor_refs_.size()) win.monitors.resize(monitor_refs_.size());
        win.monitors[*monitor].add(tw, v);
      }
    }
  }
}

std::optional<std::size_t> MotionClassifier::monitor_of(const std::string& device, const std::string& signal) const {
  for (std::size_t m = 0; m < monitor_refs_.size(); ++m)
    if (device == monitor_refs_[m].first && signal == monitor_refs_[m].second) return m;
  return std::nullopt;
}

double MotionClassifier::vibration_threshold() const {
  std::vector<double> sds;
  for (const auto& [w, win] : windows_) {
    double sd = 0.0;
    for (const LineSums& s : win.monitors) sd = std::max(sd, s.detrended_sd());
    if (!win.monitors.empty()) sds.push_back(sd);
  }
  if (sds.empty()) return kVibrationFloor;
  const auto k = static_cast<std::size_t>(kFloorPercentile * static_cast<double>(sds.size() - 1));
  std::nth_element(sds.begin(), sds.begin() + static_cast<std::ptrdiff_t>(k), sds.end());
  return std::max(kVibrationFloor, kVibrationOverFloor * sds[k]);
}

std::vector<MotionRun> MotionClassifier::runs() const {
  const double threshold = vibration_threshold();
  std::vector<MotionRun> runs;
  std::vector<std::pair<std::int64_t, std::int64_t>> span;   // each run's first and last window
  for (const auto& [w, win] : windows_) {
    MotionClass c = MotionClass::Static;
    const double dt = win.last_t - win.first_t;
    double sd = 0.0;
    for (const LineSums& s : win.monitors) sd = std::max(sd, s.detrended_sd());
    if (win.turned_known && dt > 0 && std::abs(win.last_angle - win.first_angle) / dt > kRotationRate) {
      c = MotionClass::Rotation;
    } else if (sd > threshold) {
      c = MotionClass::Vibration;
    }
    const double start = static_cast<double>(w) * window_ns_;
    if (!runs.empty() && runs.back().motion == c && runs.back().end_ns >= start - 0.5 * window_ns_) {
      runs.back().end_ns = start + window_ns_;
      span.back().second = w;
    } else {
      runs.push_back({c, start, start + window_ns_});
      span.emplace_back(w, w);
    }
  }
  // A rotation begins and ends within a window, usually the quiet one beside it (a smooth rate
  // profile starts too slowly to count over a whole window): to the sample where the table moved.
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (runs[i].motion != MotionClass::Rotation) continue;
    const auto moved = [this](std::int64_t w, bool first) {
      const auto it = windows_.find(w);
      if (it == windows_.end()) return std::numeric_limits<double>::quiet_NaN();
      return first ? it->second.move_first_ns : it->second.move_last_ns;
    };
    double start = moved(span[i].first - 1, true);
    if (std::isnan(start)) start = moved(span[i].first, true);
    double end = moved(span[i].second + 1, false);
    if (std::isnan(end)) end = moved(span[i].second, false);
    if (!std::isnan(start)) {
      runs[i].start_ns = start;
      if (i > 0) runs[i - 1].end_ns = start;
    }
    if (!std::isnan(end)) {
      runs[i].end_ns = end;
      if (i + 1 < runs.size()) runs[i + 1].start_ns = end;
    }
  }
  // A run shorter than two windows (a ramp, a bump) joins the run before it (the first one joins
  // the next); neighbours of one class then become one run.
  for (bool changed = true; changed && runs.size() > 1;) {
    changed = false;
    for (std::size_t i = 0; i < runs.size(); ++i) {
      if (runs[i].end_ns - runs[i].start_ns >= 2.0 * window_ns_) continue;
      if (i > 0) {
        runs[i - 1].end_ns = runs[i].end_ns;
      } else {
        runs[1].start_ns = runs[0].start_ns;
      }
      runs.erase(runs.begin() + static_cast<std::ptrdiff_t>(i));
      for (std::size_t k = 1; k < runs.size();) {
        if (runs[k].motion == runs[k - 1].motion) {
          runs[k - 1].end_ns = runs[k].end_ns;
          runs.erase(runs.begin() + static_cast<std::ptrdiff_t>(k));
        } else {
          ++k;
        }
      }
      changed = true;
      break;
    }
  }
  return runs;
}

VibrationEdgeRefiner::VibrationEdgeRefiner(const MotionClassifier& motion, std::vector<MotionRun> runs)
    : motion_(motion), runs_(std::move(runs)) {
  const auto vibration_edge = [](MotionClass a, MotionClass b) {
    return (a == MotionClass::Static && b == MotionClass::Vibration) || (a == MotionClass::Vibration && b == MotionClass::Static);
  };
  for (std::size_t i = 0; i + 1 < runs_.size(); ++i) {
    if (!vibration_edge(runs_[i].motion, runs_[i + 1].motion)) continue;
    const double edge = runs_[i].end_ns;
    edges_.push_back({i, std::max(runs_[i].start_ns, edge - motion.window_ns()), std::min(runs_[i + 1].end_ns, edge + motion.window_ns()),
                      std::vector<std::vector<std::pair<double, double>>>(motion.monitor_count())});
  }
}

void VibrationEdgeRefiner::push(const sample_block_t& block) {
  if (edges_.empty() || block.num_samples <= 0 || !block_shape_error(block).empty()) return;
  const double period_ns = block.sample_period_s * 1e9;
  const double first = static_cast<double>(block.t0_mono_ns), last = first + period_ns * (block.num_samples - 1);
  for (std::int32_t c = 0; c < block.num_channels; ++c) {
    const std::optional<std::size_t> monitor = motion_.monitor_of(block.device, block.channel_names[static_cast<std::size_t>(c)]);
    if (!monitor) continue;
    for (Edge& e : edges_) {
      if (last < e.from_ns || first >= e.to_ns) continue;
      for (std::int32_t s = 0; s < block.num_samples; ++s) {
        const double t = first + period_ns * s;
        const double v = block.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)];
        if (t >= e.from_ns && t < e.to_ns && sample_valid(block, c, s) && std::isfinite(v)) e.samples[*monitor].emplace_back(t, v);
      }
    }
  }
}

std::vector<MotionRun> VibrationEdgeRefiner::runs() const {
  std::vector<MotionRun> out = runs_;
  for (const Edge& e : edges_) {
    // Per monitor, prefix sums of (t - from) in s and (y - its first value), so that the
    // residual sum of squares of a line through any leading or trailing stretch is a difference.
    struct Prefix {
      std::vector<double> t;        // sample times (ns), sorted
      std::vector<LineSums> sums;   // of the samples before sample k
    };
    std::vector<Prefix> prefix;
    for (std::vector<std::pair<double, double>> samples : e.samples) {
      if (samples.size() < 6) continue;
      std::sort(samples.begin(), samples.end());
      Prefix p;
      p.sums.emplace_back();
      // Offsets keep the sums' differences well conditioned (gravity dwarfs the noise).
      const double y0 = samples.front().second;
      for (const auto& [t, v] : samples) {
        LineSums next = p.sums.back();
        next.add((t - e.from_ns) * 1e-9, v - y0);
        p.t.push_back(t);
        p.sums.push_back(next);
      }
      prefix.push_back(std::move(p));
    }
    if (prefix.empty()) continue;
    // A side of pure simulated rest has no noise: its variance is floored far below any real
    // sensor's, so that the likelihood stays finite and still prefers the clean split.
    double floor = std::numeric_limits<double>::min();
    for (const Prefix& p : prefix) floor = std::max(floor, 1e-12 * (p.sums.back() - p.sums.front()).residual_ss() / p.sums.back().n);
    std::vector<std::pair<double, double>> costs;   // (split, cost)
    for (std::size_t k = 3; k + 3 <= prefix.front().t.size(); ++k) {
      const double split = prefix.front().t[k];   // the first sample of the later run
      double cost = 0.0;
      bool usable = true;
      for (const Prefix& p : prefix) {
        const auto at = static_cast<std::size_t>(std::lower_bound(p.t.begin(), p.t.end(), split) - p.t.begin());
        const std::size_t n = p.t.size();
        if (at < 3 || n - at < 3) {
          usable = false;
          break;
        }
        const double n1 = static_cast<double>(at), n2 = static_cast<double>(n - at);
        cost += n1 * std::log(std::max((p.sums[at] - p.sums.front()).residual_ss() / n1, floor)) +
                n2 * std::log(std::max((p.sums.back() - p.sums[at]).residual_ss() / n2, floor));
      }
      if (usable) costs.emplace_back(split, cost);
    }
    if (costs.empty()) continue;
    // The cost is -2 log-likelihood up to a constant: the splits within kEdgeLikelihoodRatio of
    // the best are where the change may lie, and their rows belong to neither run.
    double best = std::numeric_limits<double>::infinity();
    for (const auto& [split, cost] : costs) best = std::min(best, cost);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const auto& [split, cost] : costs) {
      if (cost - best > kEdgeLikelihoodRatio) continue;
      lo = std::min(lo, split);
      hi = std::max(hi, split);
    }
    out[e.run].end_ns = lo;
    out[e.run + 1].start_ns = hi;
  }
  return out;
}

Segmentation segment_plan(const config::BenchConfig& bench, const std::vector<MotionRun>& runs, double origin_ns) {
  // The plan's phases in order, each with the run (of merged equal classes) it falls in.
  struct Entry {
    std::size_t case_index, phase_index, run;
  };
  std::vector<Entry> entries;
  std::vector<MotionClass> expected;
  for (std::size_t c = 0; c < bench.cases.size(); ++c) {
    for (std::size_t p = 0; p < bench.cases[c].phases.size(); ++p) {
      const config::Phase& ph = bench.cases[c].phases[p];
      if (ph.kind == config::PhaseKind::Shock)
        throw InputError("the log has no plan markers, and case " + bench.cases[c].name +
                         " has a shock phase: a pulse within a quiet phase cannot be told from the references' "
                         "motion; mark the phases (inertia-daqd mark) when recording");
      const MotionClass m = class_of(ph.kind);
      if (expected.empty() || expected.back() != m) expected.push_back(m);
      entries.push_back({c, p, expected.size() - 1});
    }
  }
  // Rest before the plan's first motion or after its last (the daemon records before the first
  // case and after the last) belongs to no phase when the plan does not start or end at rest.
  std::size_t first = 0, last = runs.size();
  if (!runs.empty() && !expected.empty() && expected.front() != MotionClass::Static && runs.front().motion == MotionClass::Static)
    first = 1;
  if (last > first && !expected.empty() && expected.back() != MotionClass::Static && runs.back().motion == MotionClass::Static)
    --last;
  const std::vector<MotionRun> used(runs.begin() + static_cast<std::ptrdiff_t>(first), runs.begin() + static_cast<std::ptrdiff_t>(last));
  std::vector<MotionClass> found;
  for (const MotionRun& r : used) found.push_back(r.motion);
  if (found != expected)
    throw InputError("the log has no plan markers, and the references' motion (" + sequence(found) +
                     ") does not match the plan's phases (" + sequence(expected) +
                     ") once neighbours of one kind merge: the cases cannot be told apart. Mark the phases "
                     "(inertia-daqd mark) when recording");
  const auto sec = [origin_ns](double t) { return (t - origin_ns) * 1e-9; };
  struct Placed {
    std::size_t case_index;
    std::vector<double> bounds;      // phase starts, then the case's end
    std::vector<bool> detected;      // each bound detected (else placed by the plan's durations)
    std::vector<const Entry*> phases;
  };
  std::vector<Placed> placed;
  Segmentation out;
  for (std::size_t c = 0; c < bench.cases.size(); ++c) {
    const config::TestCase& tc = bench.cases[c];
    std::vector<const Entry*> ph;
    for (const Entry& e : entries)
      if (e.case_index == c) ph.push_back(&e);
    if (ph.empty()) continue;
    const std::size_t n = ph.size();
    // bounds[i]: start of phase i; bounds[n]: the case's end. Detected where the class changes
    // within the case, and where the case's first (last) phase opens (closes) its run alone.
    std::vector<std::optional<double>> bounds(n + 1);
    std::vector<bool> detected(n + 1, false);
    const auto alone_first = [&](std::size_t i) {
      return std::none_of(entries.begin(), entries.end(), [&](const Entry& e) {
        return e.run == ph[i]->run && (e.case_index < c || (e.case_index == c && e.phase_index < ph[i]->phase_index));
      });
    };
    const auto alone_last = [&](std::size_t i) {
      return std::none_of(entries.begin(), entries.end(), [&](const Entry& e) {
        return e.run == ph[i]->run && (e.case_index > c || (e.case_index == c && e.phase_index > ph[i]->phase_index));
      });
    };
    // The log's first and last samples are no change of motion: the daemon may have recorded
    // before the plan began and after it ended. They anchor a case only when nothing else does.
    const bool at_log_start = ph[0]->run == 0 && first == 0;
    const bool at_log_end = ph[n - 1]->run + 1 == used.size() && last == runs.size();
    if (alone_first(0) && !at_log_start) bounds[0] = used[ph[0]->run].start_ns;
    for (std::size_t i = 1; i < n; ++i)
      if (ph[i]->run != ph[i - 1]->run) bounds[i] = used[ph[i]->run].start_ns;
    if (alone_last(n - 1) && !at_log_end) bounds[n] = used[ph[n - 1]->run].end_ns;
    for (std::size_t i = 0; i <= n; ++i) detected[i] = bounds[i].has_value();
    if (std::none_of(bounds.begin(), bounds.end(), [](const auto& x) { return x.has_value(); })) {
      if (alone_first(0) && at_log_start) {
        bounds[0] = used[ph[0]->run].start_ns;
      } else if (alone_last(n - 1) && at_log_end) {
        bounds[n] = used[ph[n - 1]->run].end_ns;
      } else {
        throw InputError("the log has no plan markers, and case " + tc.name +
                         " lies within one stretch of one kind of motion with its neighbours: where it starts "
                         "cannot be told. Mark the phases (inertia-daqd mark) when recording");
      }
    }
    // The rest by the plan's durations: back from a later boundary first (the change that ends a
    // dwell is the one that belongs to its case), then forward.
    for (std::size_t i = n; i-- > 0;)
      if (!bounds[i] && bounds[i + 1]) bounds[i] = *bounds[i + 1] - tc.phases[ph[i]->phase_index].duration_s * 1e9;
    for (std::size_t i = 1; i <= n; ++i)
      if (!bounds[i] && bounds[i - 1]) bounds[i] = *bounds[i - 1] + tc.phases[ph[i - 1]->phase_index].duration_s * 1e9;
    // Within the runs that hold them.
    for (std::size_t i = 0; i < n; ++i) {
      const MotionRun& r = used[ph[i]->run];
      bounds[i] = std::clamp(*bounds[i], r.start_ns, r.end_ns);
      bounds[i + 1] = std::clamp(*bounds[i + 1], *bounds[i], r.end_ns);
    }
    std::vector<double> b;
    for (const auto& x : bounds) b.push_back(*x);
    placed.push_back({c, std::move(b), std::move(detected), std::move(ph)});
  }
  // A case placed by durations may reach into the next one (a dwell shorter than planned): it
  // ends where the next begins.
  for (std::size_t k = 0; k + 1 < placed.size(); ++k) {
    std::vector<double>& cur = placed[k].bounds;
    const double next = placed[k + 1].bounds.front();
    for (double& x : cur) x = std::min(x, next);
    // Where one case ends the other begins in the same rest (an instant remount) or at a change
    // the references time only to a few samples (a sine starts at zero, a band-limited random may
    // fall quiet before it ends), a row given the wrong case carries the other mounting's gravity:
    // kCaseGuardSamples either side of the cut belong to neither case.
    const double guard = kCaseGuardSamples * 1e9 / bench.sample_rate_hz;
    std::vector<double>& following = placed[k + 1].bounds;
    if (following.front() - cur.back() < 2.0 * guard) {
      const double cut = 0.5 * (cur.back() + following.front());
      for (double& x : cur) x = std::min(x, cut - guard);
      for (double& x : following) x = std::max(x, cut + guard);
    }
  }
  for (const Placed& pc : placed) {
    const config::TestCase& tc = bench.cases[pc.case_index];
    const std::size_t n = pc.phases.size();
    std::string line = "  case " + tc.name + ":";
    for (std::size_t i = 0; i < n; ++i) {
      const config::Phase& p = tc.phases[pc.phases[i]->phase_index];
      line += fmt::format(" {} {:.3f}-{:.3f} s ({}{}){}", config::phase_label(p.kind), sec(pc.bounds[i]), sec(pc.bounds[i + 1]),
                          pc.detected[i] ? "detected" : "plan duration", pc.detected[i + 1] ? ", detected end" : "",
                          i + 1 < n ? "," : "");
    }
    out.description.push_back(line);
    plan_event_t start{};
    start.mark = plan_event_t::MARK_CASE_START;
    start.case_name = tc.name;
    start.kind = config::to_string(tc.kind);
    start.phase_index = -1;
    start.mono_ns = start.start_mono_ns = static_cast<std::int64_t>(pc.bounds.front());
    start.end_mono_ns = static_cast<std::int64_t>(pc.bounds.back());
    out.markers.push_back(start);
    for (std::size_t i = 0; i < n; ++i) {
      plan_event_t m = start;
      m.mark = plan_event_t::MARK_PHASE_START;
      m.phase = config::phase_label(tc.phases[pc.phases[i]->phase_index].kind);
      m.phase_index = static_cast<std::int32_t>(pc.phases[i]->phase_index);
      m.mono_ns = m.start_mono_ns = static_cast<std::int64_t>(pc.bounds[i]);
      m.end_mono_ns = static_cast<std::int64_t>(pc.bounds[i + 1]);
      out.markers.push_back(m);
    }
    plan_event_t end = start;
    end.mark = plan_event_t::MARK_CASE_END;
    end.mono_ns = end.end_mono_ns;
    out.markers.push_back(end);
  }
  return out;
}

}  // namespace inertia::fusion
