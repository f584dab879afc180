#pragma once
#include <cmath>
// One message of each inertia LCM type with known field values, shared by the C++ round-trip,
// live and Java interop tests. DecodeCheck.java asserts the same values: change both together.
// Doubles are written so that C++ and Java parse the same literal to the same bits.

#include <gtest/gtest.h>

#include <cstdint>

#include "common/lcm/sample_block_layout.hpp"
#include "inertia/daq_status_t.hpp"
#include "inertia/analyzer_status_t.hpp"
#include "inertia/model_estimate_t.hpp"
#include "inertia/structure_table_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"

namespace inertia::test {

// values[c][s] = 100 c + 0.25 s - 1.5; every sample valid except (1, 3) and (2, 9).
inline sample_block_t known_sample_block() {
  sample_block_t b;
  shape_sample_block(b, 3, 10);
  b.device = "sim_ref_1";
  b.seq = 42;
  b.t0_mono_ns = 123456789012;
  b.t0_utime = 1700000000123456;
  b.sample_period_s = 0.001;
  b.channel_ids = {10, 11, 12};
  b.channel_names = {"a_x", "a_y", "temp"};
  b.units = {"m/s^2", "m/s^2", "degC"};
  b.channel_seq = {1000, 1000, 250};
  for (int c = 0; c < 3; ++c) {
    for (int s = 0; s < 10; ++s) {
      b.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)] = 100.0 * c + 0.25 * s - 1.5;
      set_sample_valid(b, c, s, !((c == 1 && s == 3) || (c == 2 && s == 9)));
    }
  }
  return b;
}

inline daq_status_t known_daq_status() {
  daq_status_t m;
  m.utime = 1700000000000000;
  m.mono_ns = 5000000000;
  m.uptime_s = 3600.5;
  device_status_t d0;
  d0.device = "can0_ref";
  d0.state = device_status_t::STATE_ACTIVE;
  d0.sample_rate_hz = 999.5;
  d0.nominal_rate_hz = 1000.0;
  d0.samples = 3598200;
  d0.blocks = 35982;
  d0.ring_drops = 3;
  d0.ring_high_water = 17;
  d0.ring_capacity = 1024;
  d0.decode_errors = 2;
  d0.resyncs = 1;
  d0.read_time_max_us = 42.5;
  d0.num_faults = 0;
  d0.clock_drift_ppm = -37.25;
  d0.clock_residual_us = 3.5;
  d0.lost_samples = 12;
  d0.late_samples = 1;
  d0.counter_resets = 2;
  d0.short_frames = 3;
  d0.duplicate_frames = 4;
  d0.out_of_order_frames = 5;
  d0.kernel_drops = 6;
  d0.link_reopens = 7;
  d0.clock_steps = 8;
  d0.range_faults = 9;
  d0.stuck_samples = 10;
  d0.encoder_overflows = 11;
  device_status_t d1;
  d1.device = "modbus_thermal";
  d1.state = device_status_t::STATE_FAILED;
  d1.sample_rate_hz = 0.0;
  d1.nominal_rate_hz = 10.0;
  d1.samples = 120;
  d1.blocks = 12;
  d1.ring_drops = 0;
  d1.ring_high_water = 1;
  d1.ring_capacity = 64;
  d1.decode_errors = 0;
  d1.resyncs = 0;
  d1.read_time_max_us = 1500.25;
  d1.num_faults = 1;
  d1.faults = {"modbus-gone"};
  // Every field set: an LCM type leaves its numbers uninitialised.
  d1.clock_drift_ppm = 0.0;
  d1.clock_residual_us = 0.0;
  d1.lost_samples = 0;
  d1.late_samples = 0;
  d1.counter_resets = 0;
  d1.short_frames = 0;
  d1.duplicate_frames = 0;
  d1.out_of_order_frames = 0;
  d1.kernel_drops = 0;
  d1.link_reopens = 0;
  d1.clock_steps = 0;
  d1.range_faults = 4;
  d1.stuck_samples = 0;
  d1.encoder_overflows = 0;
  m.num_devices = 2;
  m.devices = {d0, d1};
  m.lcm_messages = 40000;
  m.lcm_publish_failures = 1;
  m.log_path = "/var/lib/inertia/log/run-001.lcmlog";
  m.log_bytes = 123456789;
  m.log_rotations = 2;
  m.log_write_errors = 0;
  m.log_fsync_last_ms = 1.5;
  m.log_fsync_max_ms = 12.25;
  m.num_faults = 1;
  m.faults = {"disk-slow"};
  return m;
}

inline plan_event_t known_plan_event() {
  plan_event_t m;
  m.utime = 1700000001000000;
  m.mono_ns = 6000000000;
  m.mark = plan_event_t::MARK_PHASE_START;
  m.case_name = "shaker-ia";
  m.kind = "shaker";
  m.phase = "sine";
  m.phase_index = 2;
  m.start_mono_ns = 6000000000;
  m.end_mono_ns = 36000000000;
  m.num_setpoints = 2;
  m.setpoint_names = {"frequency", "amplitude"};
  m.setpoint_values = {80.0, 19.6133};
  m.setpoint_units = {"Hz", "m/s^2"};
  return m;
}

inline model_estimate_t known_model_estimate() {
  model_estimate_t m;
  m.utime = 1700000002000000;
  m.mono_ns = 7000000000;
  m.sensor = "sut_accel_1";
  m.output_unit = "mA";
  m.num_terms = 4;
  m.terms = {"1", "a_i", "a_i^2", "a_i*abs(a_i)"};
  m.values = {3.44e-3, 0.0877, 1.5e-5, -2.0e-6};
  m.std_devs = {1.0e-6, 2.0e-6, 3.0e-7, 4.0e-7};
  m.residual_variance = 1.0e-8;
  m.misalignment_rad[0] = 1.0e-3;
  m.misalignment_rad[1] = -2.0e-3;
  m.misalignment_rad[2] = 5.0e-4;
  m.samples_used = 200000;
  m.converged = true;
  m.t_values = {3440.0, 43850.0, 50.0, -5.0};
  m.convergence = "largest leave-one-case-out z 1.20 (a_i^2 without case shaker-ia), bound 3.60";
  m.cases_used = 4;
  m.noise_ar_order = 12;
  m.square_corner_rad_s = 502.2;
  m.num_mountings = 2;
  m.mountings = {"rotation-table", "shaker-fixture"};
  m.mounting_determined = {true, false};
  m.mounting_angles_rad = {{std::nan(""), 1.0e-3, 3.5e-2}, {std::nan(""), 2.1e-2, -2.2e-2}};
  m.mounting_angles_sd_rad = {{std::nan(""), 1.0e-5, 2.0e-5}, {std::nan(""), 3.0e-6, 4.0e-6}};
  m.mounting_samples = {370000, 105000};
  m.mounting_notes = {"left out (IEEE 1293 12.3.5.7): a_p^2, a_o^2", ""};
  return m;
}

inline structure_table_t known_structure_table() {
  structure_table_t m;
  m.utime = 1700000003000000;
  m.mono_ns = 8000000000;
  m.sensor = "sut_accel_1";
  m.num_candidates = 2;
  m.terms = {"a_i*abs(a_i)", "a_i[k-1]"};
  m.effects = {"odd quadratic", "dynamics"};
  m.err = {1.5e-3, 2.0e-6};
  m.values = {2.0e-5, -1.0e-6};
  m.std_devs = {1.0e-6, 3.0e-6};
  m.t_values = {20.0, -0.33};
  m.significant = {true, false};
  return m;
}

inline analyzer_status_t known_analyzer_status() {
  analyzer_status_t m;
  m.utime = 1700000004000000;
  m.mono_ns = 9000000000;
  m.uptime_s = 12.5;
  m.bench = "sim-paper";
  m.bench_restarts = 1;
  m.received = 3303;
  m.skipped_malformed = 2;
  m.skipped_oversized = 3;
  m.skipped_invalid = 4;
  m.skipped_refused = 5;
  m.invalid_values = 6;
  m.gaps = 7;
  m.queue_drops = 8;
  m.queue_high_water = 9;
  m.cpu_percent = 12.5;
  m.latency_p50_ms = 40.0;
  m.latency_p99_ms = 95.0;
  m.latency_max_ms = 120.0;
  m.num_sensors = 1;
  m.sensors = {"acc1"};
  m.rows_fused = {470000};
  m.rows_estimated = {469000};
  m.exclusions = {2};
  m.num_notes = 1;
  m.notes = {"INERTIA_RAW_ACCEL: valid_bytes 3 for 40 samples"};
  return m;
}

// Field-by-field equality (lcm-gen emits no operator==). Exact for doubles: encoding is a
// bit copy, so anything but identity is a bug.
inline void expect_equal(const sample_block_t& a, const sample_block_t& b) {
  EXPECT_EQ(a.device, b.device);
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.t0_mono_ns, b.t0_mono_ns);
  EXPECT_EQ(a.t0_utime, b.t0_utime);
  EXPECT_EQ(a.sample_period_s, b.sample_period_s);
  EXPECT_EQ(a.num_channels, b.num_channels);
  EXPECT_EQ(a.channel_ids, b.channel_ids);
  EXPECT_EQ(a.channel_names, b.channel_names);
  EXPECT_EQ(a.units, b.units);
  EXPECT_EQ(a.channel_seq, b.channel_seq);
  EXPECT_EQ(a.num_samples, b.num_samples);
  EXPECT_EQ(a.values, b.values);
  EXPECT_EQ(a.valid_bytes, b.valid_bytes);
  EXPECT_EQ(a.valid, b.valid);
}

inline void expect_equal(const device_status_t& a, const device_status_t& b) {
  EXPECT_EQ(a.device, b.device);
  EXPECT_EQ(a.state, b.state);
  EXPECT_EQ(a.sample_rate_hz, b.sample_rate_hz);
  EXPECT_EQ(a.nominal_rate_hz, b.nominal_rate_hz);
  EXPECT_EQ(a.samples, b.samples);
  EXPECT_EQ(a.blocks, b.blocks);
  EXPECT_EQ(a.ring_drops, b.ring_drops);
  EXPECT_EQ(a.ring_high_water, b.ring_high_water);
  EXPECT_EQ(a.ring_capacity, b.ring_capacity);
  EXPECT_EQ(a.decode_errors, b.decode_errors);
  EXPECT_EQ(a.resyncs, b.resyncs);
  EXPECT_EQ(a.read_time_max_us, b.read_time_max_us);
  EXPECT_EQ(a.num_faults, b.num_faults);
  EXPECT_EQ(a.faults, b.faults);
  EXPECT_EQ(a.clock_drift_ppm, b.clock_drift_ppm);
  EXPECT_EQ(a.clock_residual_us, b.clock_residual_us);
  EXPECT_EQ(a.lost_samples, b.lost_samples);
  EXPECT_EQ(a.late_samples, b.late_samples);
  EXPECT_EQ(a.counter_resets, b.counter_resets);
  EXPECT_EQ(a.short_frames, b.short_frames);
  EXPECT_EQ(a.duplicate_frames, b.duplicate_frames);
  EXPECT_EQ(a.out_of_order_frames, b.out_of_order_frames);
  EXPECT_EQ(a.kernel_drops, b.kernel_drops);
  EXPECT_EQ(a.link_reopens, b.link_reopens);
  EXPECT_EQ(a.clock_steps, b.clock_steps);
  EXPECT_EQ(a.range_faults, b.range_faults);
  EXPECT_EQ(a.stuck_samples, b.stuck_samples);
  EXPECT_EQ(a.encoder_overflows, b.encoder_overflows);
}

inline void expect_equal(const daq_status_t& a, const daq_status_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.mono_ns, b.mono_ns);
  EXPECT_EQ(a.uptime_s, b.uptime_s);
  ASSERT_EQ(a.num_devices, b.num_devices);
  ASSERT_EQ(a.devices.size(), b.devices.size());
  for (std::size_t i = 0; i < a.devices.size(); ++i) {
    SCOPED_TRACE("device " + std::to_string(i));
    expect_equal(a.devices[i], b.devices[i]);
  }
  EXPECT_EQ(a.lcm_messages, b.lcm_messages);
  EXPECT_EQ(a.lcm_publish_failures, b.lcm_publish_failures);
  EXPECT_EQ(a.log_path, b.log_path);
  EXPECT_EQ(a.log_bytes, b.log_bytes);
  EXPECT_EQ(a.log_rotations, b.log_rotations);
  EXPECT_EQ(a.log_write_errors, b.log_write_errors);
  EXPECT_EQ(a.log_fsync_last_ms, b.log_fsync_last_ms);
  EXPECT_EQ(a.log_fsync_max_ms, b.log_fsync_max_ms);
  EXPECT_EQ(a.num_faults, b.num_faults);
  EXPECT_EQ(a.faults, b.faults);
}

inline void expect_equal(const plan_event_t& a, const plan_event_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.mono_ns, b.mono_ns);
  EXPECT_EQ(a.mark, b.mark);
  EXPECT_EQ(a.case_name, b.case_name);
  EXPECT_EQ(a.kind, b.kind);
  EXPECT_EQ(a.phase, b.phase);
  EXPECT_EQ(a.phase_index, b.phase_index);
  EXPECT_EQ(a.start_mono_ns, b.start_mono_ns);
  EXPECT_EQ(a.end_mono_ns, b.end_mono_ns);
  EXPECT_EQ(a.num_setpoints, b.num_setpoints);
  EXPECT_EQ(a.setpoint_names, b.setpoint_names);
  EXPECT_EQ(a.setpoint_values, b.setpoint_values);
  EXPECT_EQ(a.setpoint_units, b.setpoint_units);
}

inline void expect_equal(const model_estimate_t& a, const model_estimate_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.mono_ns, b.mono_ns);
  EXPECT_EQ(a.sensor, b.sensor);
  EXPECT_EQ(a.output_unit, b.output_unit);
  EXPECT_EQ(a.num_terms, b.num_terms);
  EXPECT_EQ(a.terms, b.terms);
  EXPECT_EQ(a.values, b.values);
  EXPECT_EQ(a.std_devs, b.std_devs);
  EXPECT_EQ(a.residual_variance, b.residual_variance);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(a.misalignment_rad[i], b.misalignment_rad[i]) << "angle " << i;
  EXPECT_EQ(a.samples_used, b.samples_used);
  EXPECT_EQ(a.converged, b.converged);
  EXPECT_EQ(a.t_values, b.t_values);
  EXPECT_EQ(a.convergence, b.convergence);
  EXPECT_EQ(a.cases_used, b.cases_used);
  EXPECT_EQ(a.noise_ar_order, b.noise_ar_order);
  EXPECT_EQ(a.square_corner_rad_s, b.square_corner_rad_s);
  EXPECT_EQ(a.num_mountings, b.num_mountings);
  EXPECT_EQ(a.mountings, b.mountings);
  EXPECT_EQ(a.mounting_determined, b.mounting_determined);
  ASSERT_EQ(a.mounting_angles_rad.size(), b.mounting_angles_rad.size());
  for (std::size_t m = 0; m < a.mounting_angles_rad.size(); ++m) {
    for (std::size_t i = 0; i < 3; ++i) {
      // NaN (the turn about i) must come back as NaN: compare the bits' meaning, not ==.
      EXPECT_TRUE(a.mounting_angles_rad[m][i] == b.mounting_angles_rad[m][i] ||
                  (std::isnan(a.mounting_angles_rad[m][i]) && std::isnan(b.mounting_angles_rad[m][i])));
      EXPECT_TRUE(a.mounting_angles_sd_rad[m][i] == b.mounting_angles_sd_rad[m][i] ||
                  (std::isnan(a.mounting_angles_sd_rad[m][i]) && std::isnan(b.mounting_angles_sd_rad[m][i])));
    }
  }
  EXPECT_EQ(a.mounting_samples, b.mounting_samples);
  EXPECT_EQ(a.mounting_notes, b.mounting_notes);
}

inline void expect_equal(const structure_table_t& a, const structure_table_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.mono_ns, b.mono_ns);
  EXPECT_EQ(a.sensor, b.sensor);
  EXPECT_EQ(a.num_candidates, b.num_candidates);
  EXPECT_EQ(a.terms, b.terms);
  EXPECT_EQ(a.effects, b.effects);
  EXPECT_EQ(a.err, b.err);
  EXPECT_EQ(a.values, b.values);
  EXPECT_EQ(a.std_devs, b.std_devs);
  EXPECT_EQ(a.t_values, b.t_values);
  EXPECT_EQ(a.significant, b.significant);
}

inline void expect_equal(const analyzer_status_t& a, const analyzer_status_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.bench, b.bench);
  EXPECT_EQ(a.bench_restarts, b.bench_restarts);
  EXPECT_EQ(a.received, b.received);
  EXPECT_EQ(a.skipped_malformed, b.skipped_malformed);
  EXPECT_EQ(a.skipped_oversized, b.skipped_oversized);
  EXPECT_EQ(a.skipped_invalid, b.skipped_invalid);
  EXPECT_EQ(a.skipped_refused, b.skipped_refused);
  EXPECT_EQ(a.invalid_values, b.invalid_values);
  EXPECT_EQ(a.gaps, b.gaps);
  EXPECT_EQ(a.queue_drops, b.queue_drops);
  EXPECT_EQ(a.cpu_percent, b.cpu_percent);
  EXPECT_EQ(a.latency_p99_ms, b.latency_p99_ms);
  EXPECT_EQ(a.sensors, b.sensors);
  EXPECT_EQ(a.rows_fused, b.rows_fused);
  EXPECT_EQ(a.rows_estimated, b.rows_estimated);
  EXPECT_EQ(a.exclusions, b.exclusions);
  EXPECT_EQ(a.notes, b.notes);
}

}  // namespace inertia::test
