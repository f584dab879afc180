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

double MotionClassifier::Sums::detrended_sd() const {
  if (n < 3) return 0.0;
  // Residual sum of squares of the least-squares line y = a + b t.
  const double stt = tt - t * t / n, sty = ty - t * y / n, syy = yy - y * y / n;
  const double rss = stt > 0 ? syy - sty * sty / stt : syy;
  return std::sqrt(std::max(0.0, rss) / (n - 2));
}

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
  const double period_ns = block.sample_period_s * 1e9;
  if (!(period_ns > 0.0) || block.num_samples <= 0) return;
  if (!have_origin_) {
    origin_ns_ = static_cast<double>(block.t0_mono_ns);
    have_origin_ = true;
  }
  for (std::int32_t c = 0; c < block.num_channels; ++c) {
    const std::string& name = block.channel_names[static_cast<std::size_t>(c)];
    const bool table = block.device == table_device_ && name == table_signal_;
    std::optional<std::size_t> monitor;
    for (std::size_t m = 0; m < monitor_refs_.size(); ++m)
      if (block.device == monitor_refs_[m].first && name == monitor_refs_[m].second) monitor = m;
    if (!table && !monitor) continue;
    for (std::int32_t s = 0; s < block.num_samples; ++s) {
      const double v = block.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)];
      if (!sample_valid(block, c, s) || !std::isfinite(v)) continue;
      const double t = static_cast<double>(block.t0_mono_ns) + period_ns * s;
      const auto w = static_cast<std::int64_t>(std::floor((t - origin_ns_) / window_ns_));
      Window& win = windows_[w];
      const double tw = (t - origin_ns_ - static_cast<double>(w) * window_ns_) * 1e-9;
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
        Sums& sm = win.monitors[*monitor];
        sm.n += 1;
        sm.t += tw;
        sm.tt += tw * tw;
        sm.y += v;
        sm.ty += tw * v;
        sm.yy += v * v;
      }
    }
  }
}

double MotionClassifier::vibration_threshold() const {
  std::vector<double> sds;
  for (const auto& [w, win] : windows_) {
    double sd = 0.0;
    for (const Sums& s : win.monitors) sd = std::max(sd, s.detrended_sd());
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
    for (const Sums& s : win.monitors) sd = std::max(sd, s.detrended_sd());
    if (win.turned_known && dt > 0 && std::abs(win.last_angle - win.first_angle) / dt > kRotationRate) {
      c = MotionClass::Rotation;
    } else if (sd > threshold) {
      c = MotionClass::Vibration;
    }
    const double start = origin_ns_ + static_cast<double>(w) * window_ns_;
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
  }
  for (const Placed& pc : placed) {
    const config::TestCase& tc = bench.cases[pc.case_index];
    const std::size_t n = pc.phases.size();
    std::string line = "  case " + tc.name + ":";
    for (std::size_t i = 0; i < n; ++i) {
      const config::Phase& p = tc.phases[pc.phases[i]->phase_index];
      line += fmt::format(" {} {:.2f}-{:.2f} s ({}{}){}", config::phase_label(p.kind), sec(pc.bounds[i]), sec(pc.bounds[i + 1]),
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
