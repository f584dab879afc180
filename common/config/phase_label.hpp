#pragma once
// The name a phase kind has in a dataset's phase column and on INERTIA_EVENT (docs/design.md, dataset
// folder): the simulator, the daemon's markers and the analyzer's log segmenter all use it.
#include "common/config/bench_config.hpp"

namespace inertia::config {

constexpr const char* phase_label(PhaseKind kind) noexcept {
  switch (kind) {
    case PhaseKind::Dwell: return "static";
    case PhaseKind::Rotation: return "rotation";
    case PhaseKind::Sine: return "sine";
    case PhaseKind::Random: return "random";
    case PhaseKind::Shock: return "shock";
    case PhaseKind::ThermalStep: return "thermal";
  }
  return "?";
}

}  // namespace inertia::config
