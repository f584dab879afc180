#pragma once
// A test-plan marker's names and setpoints (plan_event_t), from the bench's plan: one
// description for the simulated bench's markers and the test executive's (daq/test_executive.hpp),
// so a marker reads the same whoever ran the phase. Not real-time (strings).
#include "common/config/bench_config.hpp"
#include "daq/publisher.hpp"
#include "inertia/plan_event_t.hpp"

namespace inertia::daq {

/// Fills case_name, kind, phase and the phase's setpoints (SI) of `event` for `mark`. A mark
/// outside the plan (case or phase index out of range) leaves them empty. Publisher thread.
void describe_plan_mark(const config::BenchConfig& bench, const PlanMark& mark, plan_event_t& event);

}  // namespace inertia::daq
