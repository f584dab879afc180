#pragma once
// The edge events a real x4 quadrature encoder produces for a displacement trace, with optional
// injected faults; the simulator's encoder wire and the decoder tests use it.
// Quantisation: count = floor(x / resolution); each count boundary crossed is one edge at the
// linearly interpolated crossing time (gray sequence in quadrature_decoder.hpp). Timestamps are
// made strictly increasing (1 ns apart at least), as distinct kernel stamps are.
#include <cstdint>
#include <functional>
#include <vector>

#include "hal/gpiod/quadrature_decoder.hpp"

namespace inertia::hal::wire_sim {

struct QuadratureFaults {
  std::size_t pulse_every = 0;         // after every n-th motion edge, a pulse on the other line
  std::int64_t pulse_width_ns = 500;   // shorter than the decoder's min_edge_interval_ns
  std::int64_t pulse_clearance_ns = 0; // a pulse only where the gap to the next edge exceeds this
  std::size_t duplicate_every = 0;     // after every n-th motion edge, the same edge again (no level change)
  std::size_t skip_every = 0;          // every n-th motion edge stamped with its predecessor's time
};

struct SimEdge {
  gpiod::EdgeEvent event;
  std::int64_t expected_count = 0;     // what a correct decoder holds after this event
  bool injected = false;               // a glitch edge, not motion
};

struct QuadratureTrace {
  bool a0 = false, b0 = false;         // levels at the start
  std::int64_t start_count = 0;
  std::vector<SimEdge> edges;
  std::size_t pulses = 0, duplicates = 0, skips = 0;  // faults actually injected
};

/// x_of_t: displacement (SI) at time t (s). Sampled every dt_s from t0_s to t1_s; event times
/// are t0_ns + t * 1e9. Skipped states make expected_count lag the truth by the withdrawn steps.
QuadratureTrace generate_quadrature(const std::function<double(double)>& x_of_t, double resolution,
                                    double t0_s, double t1_s, double dt_s, std::int64_t t0_ns,
                                    const QuadratureFaults& faults = {});

}  // namespace inertia::hal::wire_sim
