#pragma once
// A bench file: the devices and channels of a bench (real or simulated), the sensors under test
// with their truth parameters (simulator only), the references (monitoring accelerometers, the
// shaker's control accelerometer, encoders, thermal controller), seeds, and a test plan.
//
// File layout (every shipped config/*.toml repeats this summary in its header comment):
//   [bench]                    name, backend ("sim" | "real"), sample_rate_hz, t_ref_c, seed,
//                              executive ("operator" | "plan": who runs a real bench's plan)
//   [fixture]                  alpha_deg (Fig. 2 slot angle), thermal controller in [fixture.thermal]
//   [[sensor]]                 sensors under test: name, type, output_unit, slot, position_m, seed,
//                              channel, optional case_misalignment; [sensor.truth] = the fields of
//                              AccelerometerParams / FogParams under the same names (sim only)
//   [[monitor]]                single-axis monitoring accelerometers (section 2.3 skewed layout)
//   [control_accelerometer]    the shaker's control accelerometer (vibration axis)
//   [linear_encoder] [table_encoder]  resolution, channel; wire ("gpio" | "can": how the simulator
//                              carries it)
//   [[can_device]] [[gpiod_encoder]] [[modbus_device]]   real-bench wiring (the simulator ignores it)
//   [daemon]                   inertia-daqd's run settings (every key optional; the command line wins)
//   [[case]]                   the test plan, in order: name, kind, mounting, misalignments, and
//                              [[case.phase]] tables, each with a `kind` (dwell, rotation, sine,
//                              random, shock, thermal_step). `include = ["plan.toml"]` at the top
//                              level appends the [[case]] tables of other files (paths relative to
//                              the including file), so one bench can run several plans.
// Units: as the paper's tables, accelerations in config are in g and angles in degrees (suffix
// _g, _deg); everything is converted to SI here, at the edge (docs/design.md, "Units and frames").
// Unknown keys are errors: a typo must not silently fall back to a default.
#include <array>
#include <Eigen/Dense>
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common/case_kind.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"

namespace inertia::config {

/// A small rotation given as axis and angle (frame rotation, see frames::frame_rotation).
struct AxisAngle {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  double angle_rad = 0.0;
  [[nodiscard]] frames::Dcm dcm() const { return frames::frame_rotation(axis, angle_rad); }
};

/// One truth parameter of a simulated sensor: a number or an array of numbers, kept by name with
/// its position so that the simulator (which owns the parameter structs; common may not include
/// hal/) can reject an unknown name at the right line and column.
struct TruthValue {
  std::string name;
  std::vector<double> values;   // one element for a scalar
  bool is_array = false;
  SourcePosition where;
};

enum class SensorType { Accelerometer, Gyroscope };

struct SensorUnderTest {
  std::string name;
  SensorType type = SensorType::Accelerometer;
  std::string output_unit = "mA";
  std::string slot;                                  // fixture slot name (informational)
  std::string serial;                                // the unit's serial number; empty: not stated
  std::string part;                                  // its type (part number); empty: not stated
  std::string unit;                                  // the [[unit]] it belongs to; empty: none
  int unit_axis = -1;                                // its axis in that unit (0, 1, 2: x, y, z); -1: none
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();   // in F_E, from the rotation axis/table centre
  std::uint64_t seed = 0;                            // 0: derived from [bench] seed and the sensor index
  std::string channel;                               // "<device>.<signal>" on a real bench
  AxisAngle case_misalignment;                       // slot fit, in case coordinates, composed with the case's
  std::vector<TruthValue> truth;                     // [sensor.truth], aged to `calibration`
  int calibration = 0;                               // calibration index n: [sensor.aging] drifts applied n times
  SourcePosition where;
};

/// Single-axis monitoring accelerometer (references of section 2.3). Output in m/s^2:
/// m = (1 + scale_error) * n_true . a_E + bias + white noise, n_true = misalignment applied to axis.
struct MonitorAccelerometer {
  std::string name;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();   // nominal sensitive axis in F_E (unit)
  double bias_mps2 = 0.0;
  double scale_error = 0.0;
  AxisAngle misalignment;
  double noise_sd_mps2 = 0.0;
  std::string channel;
};

/// How inertia-daqd's simulator carries an encoder to its real decoding code (`wire`, simulated
/// benches only; a real bench's wiring is its [[gpiod_encoder]] or [[can_device]] and `channel`).
enum class EncoderWire {
  // x4 quadrature edges on GPIO lines, decoded by the gpiod backend: an encoder wired to the PC.
  // Every count step is one edge event, so it suits up to some 1e5 steps a second.
  Gpio,
  // The count latched on the sample clock and sent in a CAN frame, decoded by the socketcan
  // backend: a CAN encoder or a counter module, as a bench whose encoder steps at MHz has.
  Can,
};

struct Encoder {
  bool present = false;
  double resolution = 0.0;          // m per count (linear) or rad per count (table)
  std::string channel;
  EncoderWire wire = EncoderWire::Gpio;
};

/// Fixture temperature: first-order plant dT/dt = (T_amb - T)/tau + heat_rate_max * u, with the
/// Peltier drive u in [-1, 1] from a PI controller on the setpoint (exact zero-order-hold steps).
struct ThermalController {
  double ambient_c = 25.0;
  double initial_c = 25.0;          // fixture temperature and setpoint when the plan starts
  double tau_s = 600.0;             // passive time constant of the fixture
  double heat_rate_max_c_per_s = 0.5;   // dT/dt from the Peltier at full drive, u = 1
  double kp_per_c = 0.5;            // drive per degC of error
  double ki_per_c_s = 0.005;        // drive per degC*s of integrated error
  double sensor_noise_sd_c = 0.0;   // the controller's temperature sensor (reference channel)
  std::string channel;
};

// ---- real-bench devices (parsed for inertia-daqd; the simulator ignores them) ----
// Field names and meanings follow the HAL's plain structs (hal/socketcan/frame_map.hpp,
// hal/modbus/register_map.hpp and modbus_link.hpp, hal/gpiod/encoder_device.hpp), so the daemon
// copies them across one to one; common/ cannot include hal/ (dependencies point one way).
enum class ByteOrder { LittleEndian, BigEndian };

/// Every real device has it. `optional = true`: when it cannot be opened the daemon starts
/// without it (degraded, said on the journal and INERTIA_STATUS) instead of exiting 2.
struct DeviceAvailability {
  bool optional = false;
  SourcePosition where;             // the device's table ([[can_device]], ...)
  // No sample for this long while the daemon runs is the device's fault "silent" (status channel
  // and journal): a cable pulled or a module that stopped sending is never just a rate of 0.
  double silent_timeout_s = 1.0;
  // The device's fixed delay from sample to receive stamp (its conversion, transfer, adapter),
  // ns: subtracted from its stamps before its clock fit, which cannot see a constant delay, so
  // that two adapters with different delays are put on one time base. 0: none known.
  std::int64_t latency_floor_ns = 0;
};

struct CanSignal {
  std::string name;                 // channel name within the device
  std::uint32_t id = 0;             // 11-bit (standard) or 29-bit (extended) identifier
  bool extended = false;
  unsigned byte_offset = 0;         // 0..63 (CAN FD payloads up to 64 bytes)
  unsigned bit_offset = 0;          // 0..7, as hal/socketcan/frame_map.hpp numbers bits
  unsigned bit_length = 16;         // 1..64
  ByteOrder byte_order = ByteOrder::LittleEndian;
  bool is_signed = false;
  double scale = 1.0;               // SI per count: value = scale * raw + offset
  double offset = 0.0;
  std::string unit;                 // informational
  // Raw bits (bit_length wide) the sender puts on the bus for "no valid reading": such samples
  // are marked invalid (value NaN), never a number. The bench file may give a signed signal's
  // code as its negative value (-32768 for 0x8000 in 16 bits). Unset: every raw is a reading.
  std::optional<std::uint64_t> invalid_raw;
  // The frame's sample counter (hal/socketcan/frame_map.hpp): the device is timed by its own
  // clock and a lost frame leaves exactly its samples missing.
  bool counter = false;
  // An accumulating count that rolls over at its bit_length (an encoder counter card): unwrapped
  // to 64 bits (hal/socketcan/frame_map.hpp).
  bool wraps = false;
  // Plausible readings, SI: a value outside is an invalid sample and a range fault.
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  // The same reading for this long in a row is a stuck channel: its samples are marked invalid
  // until the value moves (0: not watched; only for channels that always carry noise).
  double stuck_after_s = 0.0;
};

struct CanDevice {
  std::string name;
  std::string interface = "can0";
  double sample_rate_hz = 0.0;      // expected frame rate, for health (0: not checked)
  std::vector<CanSignal> signals;
  // What the interface must be set to (inertia-daqd --check compares; 0: not checked). fd: CAN FD
  // frames, payloads up to 64 bytes; classic CAN carries 8, and every signal must fit its frame.
  bool fd = false;
  std::uint32_t bitrate = 0;        // nominal (arbitration) bit rate, bit/s
  std::uint32_t dbitrate = 0;       // CAN FD data-phase bit rate, bit/s (needs fd)
  DeviceAvailability availability;
  SourcePosition interface_at;      // the `interface` key (the table when it is left out)
};

struct GpiodEncoder {
  std::string name;
  DeviceAvailability availability;
  SourcePosition chip_at;           // the `chip` key (the table when it is left out)
  SourcePosition line_at[4];        // line_a, line_b, line_marker, line_trigger
  std::string chip = "gpiochip0";
  int line_a = 0;
  int line_b = 0;
  int line_marker = -1;             // index mark; -1: none
  int line_trigger = -1;            // external trigger input; -1: none
  bool active_low = false;
  double resolution = 1e-6;         // SI per x4 count: m (linear) or rad (rotary)
  bool rotary = false;
  // How long after its stamp gpiolib may still be queueing an edge (its IRQ thread): merges
  // and sample ticks wait this long behind the clock.
  std::int64_t edge_latency_ns = 1'000'000;
};

enum class RegisterKind { Holding, Input };
enum class RegisterType { U16, I16, U32, I32, F32 };
enum class WordOrder { ABCD, CDAB, BADC, DCBA };

/// What the test executive (daq/test_executive.hpp) does with a register. None: a reading only.
/// The command roles are setpoints the plan's phases write (config/controller_plan.hpp says which
/// phase writes what); Fault is a status word whose set bits abort the plan; Heartbeat is the
/// register the daemon writes while it is alive, whose silence the controller answers by stopping
/// (common/config/machine_safety.hpp).
enum class RegisterRole { None, TableRate, TableAngle, ShakerRun, ShakerProfile, ThermalSetpoint, Fault, Heartbeat };

struct ModbusRegister {
  std::string name;
  int address = 0;
  RegisterKind kind = RegisterKind::Holding;
  RegisterType type = RegisterType::U16;
  WordOrder order = WordOrder::ABCD;
  double scale = 1.0;               // value (SI) = scale * raw + offset
  double offset = 0.0;
  std::string unit;
  bool writable = false;            // a setpoint: needs min/max and the device's writes_enabled
  double min = 0.0;                 // write limits (clamped), SI; set when writable
  double max = 0.0;
  // Plausible readings, SI (`range = [lo, hi]`): a reading outside is an invalid sample and a range
  // fault at every poll, and inertia-daqd --check reports it.
  double range_min = -std::numeric_limits<double>::infinity();
  double range_max = std::numeric_limits<double>::infinity();
  // As CanSignal::stuck_after_s: the same reading this long in a row is stuck (0: not watched).
  double stuck_after_s = 0.0;
  SourcePosition where;
  // ---- test executive (a register with a role; every key below needs one) ----
  RegisterRole role = RegisterRole::None;
  SourcePosition role_at;           // the `role` key
  // The safe state: written at the daemon's start, on every abort and at the plan's end, at once
  // (not ramped: the controller's own deceleration applies), and until read back. A command role
  // or a writable register without a role (a mode, brake or enable register) may have one.
  // Unset: the register is left as it is.
  std::optional<double> safe;
  // A commanded value moves toward its target by at most max_rate per second (SI/s), in steps
  // written every ramp tick; infinity: in one write (discrete roles: run, profile).
  double max_rate = std::numeric_limits<double>::infinity();
  // Settled: the reading of register `measured` (same device) within `tolerance` of the target,
  // or the status word of register `settled_by` with every bit of `settled_mask` set (0: any
  // bit), continuously for settle_s. Neither: settled as soon as the write is read back.
  std::string measured;
  double tolerance = 0.0;
  std::string settled_by;
  std::uint32_t settled_mask = 0;
  double settle_s = 0.0;
  double settle_timeout_s = 60.0;   // not settled by then: the phase fails and the plan stops
  std::uint32_t fault_mask = 0;     // role fault: a fault when reading & fault_mask != 0 (0: any bit)
  // role table_angle: the register of the same device whose `safe` value stops a move in
  // progress (the controller's mode or stop register, or its rate setpoint where a rate write
  // leaves position mode). An angle setpoint has no safe value of its own: any angle is a move.
  std::string stopped_by;
  // role heartbeat: the daemon writes a counter (min, min + 1, ..., max, min, ...) every period_s
  // while it is alive; the controller is configured to stop (its communication-loss action) when
  // no write came for timeout_s, and is at rest stop_s after that.
  double heartbeat_period_s = 0.1;
  double heartbeat_timeout_s = 0.0;
  double heartbeat_stop_s = 0.0;
};

enum class ControllerRole { Thermal, Table, Shaker };

enum class ModbusTransport { Tcp, Rtu };
enum class SerialParity { None, Even, Odd };

struct ModbusDevice {
  std::string name;
  ControllerRole role = ControllerRole::Thermal;
  ModbusTransport transport = ModbusTransport::Tcp;
  std::string host = "127.0.0.1";   // tcp
  int port = 502;
  std::string serial_port;          // rtu: the device file, e.g. /dev/ttyUSB0 or /dev/serial/by-id/...
  int baud = 19200;
  SerialParity parity = SerialParity::Even;   // Modbus over serial line, section 2.5.1: even by default
  int data_bits = 8;
  int stop_bits = 1;
  DeviceAvailability availability;
  SourcePosition endpoint_at;       // `host` (tcp) or `serial_port` (rtu)
  int unit_id = 1;
  int poll_interval_ms = 100;
  double response_timeout_s = 0.5;
  double reconnect_initial_s = 0.5;
  double reconnect_max_s = 8.0;
  int timeouts_before_reconnect = 3;
  bool writes_enabled = false;      // setpoint writes are off unless enabled (docs/design.md)
  std::vector<ModbusRegister> registers;
};

/// [daemon]: settings of inertia-daqd on this bench, each the default of the command-line option
/// of the same meaning (named in the comment), which overrides it. Unset: the daemon's default.
/// [bench.sim_timing] (simulated benches, paced runs): what real hardware does to the time
/// base, so that the daemon's real timing path (its own clocks, daq/clock_fit.hpp; numbered
/// frames) runs on the simulator: the CAN device's frames carry a counter and arrive with
/// software receive stamps, a batch late by an exponential delay of mean jitter_us; the bench's
/// sample clock runs clock_ppm fast against CLOCK_MONOTONIC; each CAN frame is lost with
/// probability frame_loss; the frame counter is counter_bits wide (rolls over at 2^counter_bits).
struct SimTiming {
  double jitter_s = 0.0;
  double clock_ppm = 0.0;
  double frame_loss = 0.0;
  int counter_bits = 32;
  bool enabled = false;            // the table is present
};

// The daemon's settings' ranges, one place for the bench file's [daemon] table and the command
// line: a value outside one is bad input, never an undefined cast.
struct DaemonLimits {
  // systemd/inertia-daqd.service's WatchdogSec: a daemon whose sampling or publishing stops is
  // restarted after this long. A controller's heartbeat timeout and a Modbus device's worst poll
  // stay within it (common/config/machine_safety.hpp).
  static constexpr double kWatchdogS = 5.0;
  static constexpr double kMaxBlockMs = 1000.0;
  static constexpr int kMaxFsyncMs = 3'600'000;
  static constexpr int kMaxLogQueue = 1 << 20;
  static constexpr int kMaxRingSamples = 1 << 28;
  static constexpr int kMaxFifoPriority = 99;   // SCHED_FIFO's range on Linux is 1..99; 0 is off
  static constexpr int kMaxCpu = 4095;
};

struct DaemonSettings {
  std::optional<std::string> log_dir;      // --log: durable event log directory
  std::optional<std::string> lcm_url;      // --lcm-url
  std::optional<std::string> state_dir;    // --state-dir: where the run record is kept (daq/run_record.hpp)
  std::optional<std::string> command_socket;   // --command-socket: requests from this machine (daq/command_socket.hpp)
  std::optional<std::string> command_key;      // --command-key: the operators' keys for signed requests
  std::optional<std::string> operator_group;   // --operator-group: who is an operator on this machine
  std::optional<double> block_ms;          // --block-ms: sample block length, > 0
  std::optional<double> rotate_mb;         // --rotate-mb: new log file past this size, > 0
  std::optional<int> fsync_ms;             // --fsync-ms: fflush + fsync period of the log, >= 1
  std::optional<int> log_queue;            // --log-queue: messages buffered for the writer, >= 4
  std::optional<int> ring_samples;         // --ring: samples buffered per device, >= 1024
  std::optional<int> fifo_priority;        // --fifo-priority: SCHED_FIFO of the sampling threads, 0 (off)..99
  std::optional<int> cpu_affinity;         // --cpu: pin the sampling threads to this CPU, -1: none
  std::optional<bool> mlock;               // --mlock: mlockall(MCL_CURRENT | MCL_FUTURE)
};

// ---- test plan ----
using inertia::CaseKind;
enum class PhaseKind { Dwell, Rotation, Sine, Random, Shock, ThermalStep };
enum class Orientation { IA, PA, OA };

struct Phase {
  PhaseKind kind = PhaseKind::Dwell;
  double duration_s = 0.0;
  // rotation: about `axis` (F_E) either at constant rate_rad_s, or through angle_rad with a smooth
  // (1 - cos) rate profile; exactly one of rate/angle is set.
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  std::optional<double> rate_rad_s;
  std::optional<double> angle_rad;
  // sine: a = amplitude sin(2 pi f t) on the plateau, smooth (C2) ramps of ramp_cycles cycles.
  double frequency_hz = 0.0;
  double amplitude_mps2 = 0.0;
  double ramp_cycles = 1.0;
  // random: flat acceleration PSD between f1 and f2 at rms_mps2; smooth (C2) tapers of ramp_s.
  double f1_hz = 0.0;
  double f2_hz = 0.0;
  double rms_mps2 = 0.0;
  double ramp_s = 0.05;
  // shock: half-sine of peak_mps2 over pulse_s, centred in the phase, with pre and post
  // compensating half-sines (compensation times longer, opposite sign) so velocity and
  // displacement return to zero.
  double peak_mps2 = 0.0;
  double pulse_s = 0.0;
  double compensation = 8.0;
  // thermal_step: new controller setpoint, held for duration_s.
  double setpoint_c = 0.0;
  // sine/random/shock on a bench whose shaker controller has a register with role
  // shaker_profile: the number of the stored profile that runs this phase.
  std::optional<int> profile;
  SourcePosition where;
  SourcePosition command_at;        // the key of what the phase commands (rate_deg_s, angle_deg, setpoint_c, profile)
};

struct TestCase {
  std::string name;
  CaseKind kind = CaseKind::Static;
  // Cases with the same mounting label share one mounting of the sensor (its case misalignment);
  // written to the dataset so the analysis estimates that misalignment once over all of them.
  std::string mounting;
  frames::Dcm m_ec = frames::Dcm::Identity();       // nominal M_E^C
  std::optional<Orientation> orientation;           // set when m_ec came from a Fig. 2 slot
  AxisAngle fixture_misalignment;                   // F_E -> true fixture frame, axis in F_E
  AxisAngle case_misalignment;                      // nominal -> true case frame, axis in F_C
  AxisAngle start_attitude;                         // rotation_table: table top relative to the lab (z up)
  /// How well the fixture places this case ([[case]] placement_error_deg): the sd per axis of the
  /// rotation between its nominal and its true placement. The simulator draws that rotation from
  /// the bench seed (a real tumble's pose is never exactly its nominal one); the dataset carries
  /// the sd (placement_sd_deg) for the analysis to propagate.
  double placement_error_rad = 0.0;
  std::vector<Phase> phases;
  SourcePosition where;

  /// A thermal case, or any case with a thermal_step phase (a rate table in the fixture): its
  /// rows carry the fixture temperature, and its plan is run for the temperature coefficients.
  [[nodiscard]] bool varies_temperature() const {
    return kind == CaseKind::Thermal ||
           std::any_of(phases.begin(), phases.end(), [](const Phase& p) { return p.kind == PhaseKind::ThermalStep; });
  }
};

/// One file of a bench: its path (as given, or as an include resolved it) and its exact text.
struct SourceFile {
  std::filesystem::path path;
  std::string text;
};

/// Who runs the plan on a real bench. Operator: the operator moves the bench and marks
/// the phases (`inertia-daqd mark`); the daemon commands nothing but the safe state. Plan: the
/// daemon's test executive commands the controllers phase by phase and marks each phase itself.
enum class Executive { Operator, Plan };

/// A triaxial unit ([[unit]]): sensor outputs in one housing, each along one axis of the unit.
/// The test plan's m_ec is then the unit's frame, and each member's case frame is the unit's turned
/// to put IRA on the member's axis (unit_axis_frame). Its serial and part are its members'.
struct Unit {
  std::string name, serial, part;
  std::array<std::string, 3> accelerometers;   // along unit x, y, z ([[unit]] accelerometers); empty: none
  std::array<std::string, 3> gyroscopes;       // along unit x, y, z ([[unit]] gyroscopes); empty: none
  SourcePosition where;
};

struct BenchConfig {
  std::filesystem::path file;
  /// The bench file and every file it included, in load order: what the daemon publishes on
  /// INERTIA_BENCH so that a log carries the bench it was recorded on.
  std::vector<SourceFile> sources;
  std::string name;
  bool simulated = true;            // backend = "sim"
  Executive executive = Executive::Operator;   // [bench] executive (real benches; the simulator runs its plan itself)
  SourcePosition executive_at;
  // [bench] stop_within_s (real benches): the longest any machine of the bench may go on after
  // the daemon's last heartbeat, the lab's stop distance in time. inertia-daqd --check holds each
  // heartbeat's timeout_s + stop_s against it. Unset: not checked (--check says so).
  std::optional<double> stop_within_s;
  SourcePosition stop_within_at;
  double sample_rate_hz = 1000.0;
  double t_ref_c = 25.0;
  std::uint64_t seed = 1;
  SimTiming sim_timing;
  double alpha_rad = 0.0;           // Fig. 2 slot angle (default 25 deg)
  std::vector<SensorUnderTest> sensors;
  std::vector<Unit> units;
  std::vector<MonitorAccelerometer> monitors;
  std::optional<MonitorAccelerometer> control_accelerometer;
  Encoder linear_encoder;
  Encoder table_encoder;
  ThermalController thermal;
  std::vector<CanDevice> can_devices;
  std::vector<GpiodEncoder> gpiod_encoders;
  std::vector<ModbusDevice> modbus_devices;
  DaemonSettings daemon;
  std::vector<TestCase> cases;
};

/// Nominal M_E^C of a Fig. 2 slot orientation (section 2.3). Orientation k (IA = 0, PA = 1,
/// OA = 2) puts case axis k at `alpha_rad` from the vibration axis x_E, towards +y_E; case axis
/// k+1 (mod 3) along z_E (up); case axis k+2 = k-1 horizontal, at 90 deg - alpha from x_E:
///   IA: IRA, YRA share the vibration (XRA up)    PA: XRA, IRA share it (YRA up)
///   OA: YRA, XRA share it (IRA up, carrying 1 g: the paper's section 3.2 remark on the third
///   configuration, "exciting PA and OA", where a vertical shaker would leave IA near zero).
/// Over the three orientations every pair of case axes shares the vibration once, so a_i a_p,
/// a_p a_o and a_o a_i are all excited.
frames::Dcm slot_orientation(Orientation orientation, double alpha_rad);

/// The nominal case axes (rows IRA, XRA, YRA) of a unit's member along unit axis `unit_axis`
/// (0, 1, 2: x, y, z), in unit coordinates: the cyclic turn that puts IRA on that axis (x: IRA,
/// XRA, YRA = x, y, z; y: y, z, x; z: z, x, y). The identity for -1 (not in a unit).
frames::Dcm unit_axis_frame(int unit_axis);

/// A sensor's nominal M_E^C in `test_case`: the case's m_ec, turned to the sensor's axis when it
/// is a unit's member (m_ec is then the unit's frame). Every reader of a sensor's nominal frame
/// (the simulator, the dataset it writes, the log's fusion, the live analyzer) takes it here.
frames::Dcm nominal_m_ec(const TestCase& test_case, int unit_axis);
frames::Dcm nominal_m_ec(const TestCase& test_case, const SensorUnderTest& sensor);

/// Parses and validates a bench file. Throws InputError with file:line:column and what was
/// expected for TOML syntax errors, wrong types, missing or unknown keys, values out of range and
/// unknown phase kinds. Not real-time: allocates, reads files.
BenchConfig load_bench_config(const std::filesystem::path& path);

/// The noise seed of sensor `index` when its table gives none: its own stream, so that adding a
/// sensor does not change the others' noise.
[[nodiscard]] std::uint64_t derived_sensor_seed(std::uint64_t bench_seed, std::size_t index);

/// Another run of the same bench: every random stream from `seed`, the sensors' included (their
/// seeds are derived when the file is read, so setting `seed` alone would leave their noise as it
/// was).
void reseed(BenchConfig& bench, std::uint64_t seed);

/// The same from texts in memory (an INERTIA_BENCH message): sources[0] is the bench file, the
/// others are the files its includes name, looked up by path (resolved as load_bench_config
/// resolves them). Same validation and errors, positions naming the recorded paths; an include
/// missing from `sources` is an error at the include. Throws InputError when `sources` is empty.
BenchConfig load_bench_config_from_sources(const std::vector<SourceFile>& sources);

using inertia::to_string;
const char* to_string(PhaseKind kind);
const char* to_string(SensorType type);
const char* to_string(Orientation orientation);
const char* to_string(RegisterRole role);   // as in the bench file: "table_rate", ...

}  // namespace inertia::config
