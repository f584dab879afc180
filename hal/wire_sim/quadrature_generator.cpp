#include "hal/wire_sim/quadrature_generator.hpp"

#include <algorithm>
#include <cmath>

namespace inertia::hal::wire_sim {
namespace {

using gpiod::EdgeLine;

bool level_a(std::int64_t count) { return ((count % 4) + 4) % 4 == 1 || ((count % 4) + 4) % 4 == 2; }
bool level_b(std::int64_t count) { return ((count % 4) + 4) % 4 >= 2; }

}  // namespace

QuadratureTrace generate_quadrature(const std::function<double(double)>& x_of_t, double resolution,
                                    double t0_s, double t1_s, double dt_s, std::int64_t t0_ns,
                                    const QuadratureFaults& faults) {
  QuadratureTrace trace;
  double x_prev = x_of_t(t0_s);
  std::int64_t count = static_cast<std::int64_t>(std::floor(x_prev / resolution));
  trace.start_count = count;
  trace.a0 = level_a(count);
  trace.b0 = level_b(count);

  // Motion edges first; faults are applied in a second pass that knows the next edge's time.
  std::vector<SimEdge> motion;
  std::int64_t last_ns = t0_ns - 1;
  const auto steps = static_cast<std::int64_t>(std::ceil((t1_s - t0_s) / dt_s));
  for (std::int64_t k = 1; k <= steps; ++k) {
    const double t_prev = t0_s + static_cast<double>(k - 1) * dt_s;
    const double t = std::min(t1_s, t0_s + static_cast<double>(k) * dt_s);
    const double x = x_of_t(t);
    const auto target = static_cast<std::int64_t>(std::floor(x / resolution));
    while (count != target) {
      const std::int64_t next = target > count ? count + 1 : count - 1;
      // The boundary between count and next sits at max(count, next) * resolution.
      const double boundary = static_cast<double>(std::max(count, next)) * resolution;
      const double frac = x == x_prev ? 0.0 : std::clamp((boundary - x_prev) / (x - x_prev), 0.0, 1.0);
      std::int64_t t_ns = t0_ns + std::llround((t_prev + frac * (t - t_prev)) * 1e9);
      if (t_ns <= last_ns) t_ns = last_ns + 1;
      last_ns = t_ns;
      const bool a_changed = level_a(count) != level_a(next);
      SimEdge e;
      e.event.line = a_changed ? EdgeLine::A : EdgeLine::B;
      e.event.rising = a_changed ? level_a(next) : level_b(next);
      e.event.t_ns = t_ns;
      e.expected_count = next;
      motion.push_back(e);
      count = next;
    }
    x_prev = x;
  }

  std::int64_t withdrawn = 0;  // steps lost to skipped states so far
  bool a = trace.a0, b = trace.b0;
  std::size_t since_skip = 0;
  for (std::size_t i = 0; i < motion.size(); ++i) {
    SimEdge e = motion[i];
    const std::size_t n = i + 1;
    ++since_skip;
    // A skipped state: this edge at the same time as the previous motion edge on the other
    // line, which the decoder accepted (not right after another skip or an injected glitch).
    if (faults.skip_every != 0 && n % faults.skip_every == 0 && i > 0 && since_skip > 2 &&
        !trace.edges.empty() && !trace.edges.back().injected &&
        trace.edges.back().event.line != e.event.line) {
      // The decoder withdraws the previous step and does not count this one.
      const std::int64_t before_prev = i >= 2 ? motion[i - 2].expected_count : trace.start_count;
      withdrawn += motion[i].expected_count - before_prev;
      e.event.t_ns = trace.edges.back().event.t_ns;
      ++trace.skips;
      since_skip = 0;
    }
    e.expected_count -= withdrawn;
    (e.event.line == EdgeLine::A ? a : b) = e.event.rising;
    trace.edges.push_back(e);
    const std::int64_t next_ns = i + 1 < motion.size() ? motion[i + 1].event.t_ns : e.event.t_ns + 1'000'000'000;
    if (faults.duplicate_every != 0 && n % faults.duplicate_every == 0 && since_skip > 0 &&
        next_ns - e.event.t_ns > 2) {
      SimEdge d = e;
      d.event.t_ns = e.event.t_ns + 1;
      d.injected = true;
      trace.edges.push_back(d);
      ++trace.duplicates;
    } else if (faults.pulse_every != 0 && n % faults.pulse_every == 0 && since_skip > 0 &&
               next_ns - e.event.t_ns > faults.pulse_clearance_ns + faults.pulse_width_ns) {
      // A short pulse on the line that did not just move, centred in the gap.
      const EdgeLine line = e.event.line == EdgeLine::A ? EdgeLine::B : EdgeLine::A;
      const bool level = line == EdgeLine::A ? a : b;
      const std::int64_t start = e.event.t_ns + (next_ns - e.event.t_ns - faults.pulse_width_ns) / 2;
      SimEdge p1{{line, !level, start}, e.expected_count, true};
      SimEdge p2{{line, level, start + faults.pulse_width_ns}, e.expected_count, true};
      trace.edges.push_back(p1);
      trace.edges.push_back(p2);
      ++trace.pulses;
    }
  }
  return trace;
}

}  // namespace inertia::hal::wire_sim
