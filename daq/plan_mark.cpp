#include "daq/plan_mark.hpp"

#include "common/config/phase_label.hpp"

namespace inertia::daq {

void describe_plan_mark(const config::BenchConfig& bench, const PlanMark& mark, plan_event_t& ev) {
  if (mark.case_index < 0 || static_cast<std::size_t>(mark.case_index) >= bench.cases.size()) return;
  const auto& tc = bench.cases[static_cast<std::size_t>(mark.case_index)];
  ev.case_name = tc.name;
  ev.kind = config::to_string(tc.kind);
  if (mark.phase_index < 0 || static_cast<std::size_t>(mark.phase_index) >= tc.phases.size()) return;
  const auto& p = tc.phases[static_cast<std::size_t>(mark.phase_index)];
  ev.phase = config::phase_label(p.kind);
  auto add = [&](const char* name, double v, const char* unit) {
    ev.setpoint_names.emplace_back(name);
    ev.setpoint_values.push_back(v);
    ev.setpoint_units.emplace_back(unit);
  };
  switch (p.kind) {
    case config::PhaseKind::Rotation:
      if (p.rate_rad_s) add("rate", *p.rate_rad_s, "rad/s");
      if (p.angle_rad) add("angle", *p.angle_rad, "rad");
      break;
    case config::PhaseKind::Sine:
      add("frequency", p.frequency_hz, "Hz");
      add("amplitude", p.amplitude_mps2, "m/s^2");
      break;
    case config::PhaseKind::Random:
      add("f1", p.f1_hz, "Hz");
      add("f2", p.f2_hz, "Hz");
      add("rms", p.rms_mps2, "m/s^2");
      break;
    case config::PhaseKind::Shock:
      add("peak", p.peak_mps2, "m/s^2");
      add("pulse", p.pulse_s, "s");
      break;
    case config::PhaseKind::ThermalStep: add("temperature", p.setpoint_c, "degC"); break;
    case config::PhaseKind::Dwell: break;
  }
}

}  // namespace inertia::daq
