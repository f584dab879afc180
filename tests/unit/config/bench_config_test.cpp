// Bench file loader: every shipped config loads; every kind of bad file names file:line:column
// and what was expected; Fig. 2 slot orientations against independently built rotations.
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/config/bench_config.hpp"
#include "common/config/link_capacity.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"

namespace {

using inertia::InputError;
using namespace inertia::config;
namespace fs = std::filesystem;

const fs::path kConfigDir = fs::path(INERTIA_SOURCE_DIR) / "config";

// A minimal valid bench; tests splice faults into it.
const char* const kMinimal = R"([bench]
name = "t"
sample_rate_hz = 1000.0

[[sensor]]
name = "acc"
type = "accelerometer"

[[case]]
name = "c1"
kind = "shaker"
orientation = "IA"
[[case.phase]]
kind = "sine"
frequency_hz = 10.0
amplitude_g = 1.0
duration_s = 1.0
)";

class TempFiles : public ::testing::Test {
 protected:
  fs::path write(const std::string& name, const std::string& text) {
    const fs::path dir = fs::temp_directory_path() /
                         ("inertia_config_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                          "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir);
    const fs::path p = dir / name;
    std::ofstream(p) << text;
    return p;
  }
  // Loads `text` and returns the InputError it must raise.
  InputError error_of(const std::string& text, fs::path* file = nullptr) {
    const fs::path p = write("bench.toml", text);
    if (file != nullptr) *file = p;
    try {
      (void)load_bench_config(p);
    } catch (const InputError& e) {
      return e;
    }
    ADD_FAILURE() << "no InputError for:\n" << text;
    return InputError("none");
  }
};

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(ShippedConfigs, AllFiveLoad) {
  const char* names[] = {"sim-paper.toml", "sim-shaker.toml", "sim-rotation-table.toml", "sim-thermal.toml",
                         "bench-template.toml"};
  for (const char* n : names) {
    SCOPED_TRACE(n);
    BenchConfig b;
    ASSERT_NO_THROW(b = load_bench_config(kConfigDir / n));
    EXPECT_FALSE(b.cases.empty());
    EXPECT_FALSE(b.sensors.empty());
  }
  std::size_t toml_files = 0;
  for (const auto& e : fs::directory_iterator(kConfigDir)) {
    if (e.path().extension() != ".toml") continue;
    ++toml_files;
    SCOPED_TRACE(e.path().string());
    EXPECT_NO_THROW((void)load_bench_config(e.path()));
  }
  EXPECT_GE(toml_files, 5u);
}

TEST(ShippedConfigs, PaperExperimentIsSection3) {
  const BenchConfig b = load_bench_config(kConfigDir / "sim-paper.toml");
  EXPECT_TRUE(b.simulated);
  EXPECT_DOUBLE_EQ(b.sample_rate_hz, 10000.0);
  EXPECT_NEAR(b.alpha_rad, inertia::deg_to_rad(25.0), 1e-15);
  ASSERT_EQ(b.sensors.size(), 1u);
  ASSERT_EQ(b.cases.size(), 4u);
  const TestCase& table = b.cases[0];
  EXPECT_EQ(table.kind, CaseKind::RotationTable);
  EXPECT_NEAR(table.case_misalignment.angle_rad, inertia::deg_to_rad(2.0), 1e-15);
  int rotations = 0;
  for (const Phase& p : table.phases) rotations += p.kind == PhaseKind::Rotation;
  EXPECT_EQ(rotations, 4);   // one about each case axis and one about [1,1,1]
  const Orientation expected[] = {Orientation::IA, Orientation::PA, Orientation::OA};
  for (int i = 0; i < 3; ++i) {
    const TestCase& c = b.cases[static_cast<std::size_t>(i + 1)];
    EXPECT_EQ(c.kind, CaseKind::Shaker);
    ASSERT_TRUE(c.orientation.has_value());
    EXPECT_EQ(*c.orientation, expected[i]);
    ASSERT_EQ(c.phases.size(), 3u);
    EXPECT_EQ(c.phases[0].kind, PhaseKind::Dwell);
    EXPECT_DOUBLE_EQ(c.phases[0].duration_s, 1.0);
    EXPECT_EQ(c.phases[1].kind, PhaseKind::Sine);
    EXPECT_DOUBLE_EQ(c.phases[1].frequency_hz, 10.0);
    EXPECT_DOUBLE_EQ(c.phases[1].amplitude_mps2, 30.0 * inertia::kStandardGravity);
    EXPECT_EQ(c.phases[2].kind, PhaseKind::Random);
    EXPECT_DOUBLE_EQ(c.phases[2].rms_mps2, 17.0 * inertia::kStandardGravity);
    EXPECT_DOUBLE_EQ(c.phases[2].duration_s, 1.5);
    EXPECT_TRUE(c.case_misalignment.axis.normalized().isApprox(Eigen::Vector3d(1, 1, 1).normalized()));
  }
}

TEST(ShippedConfigs, TemplateKeepsRealBenchWiring) {
  const BenchConfig b = load_bench_config(kConfigDir / "bench-template.toml");
  EXPECT_FALSE(b.simulated);
  // Every 10 kHz adapter on CAN FD, one frame per sample with a frame counter; the
  // encoders through a counter on CAN FD, none on GPIO (their edge rates would not fit).
  ASSERT_EQ(b.can_devices.size(), 3u);
  EXPECT_EQ(b.can_devices[0].signals[1].byte_offset, 3u);
  EXPECT_EQ(b.can_devices[1].signals[0].id, 0x201u);
  EXPECT_FALSE(b.can_devices[1].signals[0].extended);
  EXPECT_EQ(b.can_devices[1].signals[0].byte_order, ByteOrder::BigEndian);
  EXPECT_EQ(*b.can_devices[0].signals[0].invalid_raw, 0x800000u);  // -8388608 in 24 signed bits
  EXPECT_DOUBLE_EQ(b.can_devices[0].availability.silent_timeout_s, 0.5);
  EXPECT_DOUBLE_EQ(b.can_devices[1].availability.silent_timeout_s, 1.0);  // the default
  for (const CanDevice& d : b.can_devices) {
    EXPECT_TRUE(d.fd) << d.name;
    EXPECT_EQ(std::count_if(d.signals.begin(), d.signals.end(), [](const CanSignal& s) { return s.counter; }), 1) << d.name;
  }
  for (const CanBusLoad& l : can_bus_loads(b)) EXPECT_LT(l.load, kMaxCanBusLoad) << l.interface;
  EXPECT_TRUE(b.gpiod_encoders.empty());
  EXPECT_EQ(b.table_encoder.channel, "enc.table");
  EXPECT_EQ(b.linear_encoder.channel, "enc.armature");
  ASSERT_EQ(b.modbus_devices.size(), 3u);
  EXPECT_FALSE(b.modbus_devices[0].writes_enabled);   // off by default
  const ModbusRegister& sp = b.modbus_devices[0].registers[1];
  EXPECT_TRUE(sp.writable);
  EXPECT_DOUBLE_EQ(sp.min, 0.0);
  EXPECT_DOUBLE_EQ(sp.max, 60.0);
  // [daemon]: every key the template documents is read.
  EXPECT_EQ(b.daemon.log_dir.value_or(""), "/var/lib/inertia/log");
  EXPECT_FALSE(b.daemon.lcm_url.has_value());  // commented out
  EXPECT_EQ(b.daemon.fifo_priority.value_or(0), 80);
  EXPECT_EQ(b.daemon.cpu_affinity.value_or(-1), 1);
  EXPECT_TRUE(b.daemon.mlock.value_or(false));
  EXPECT_DOUBLE_EQ(b.daemon.block_ms.value_or(0.0), 10.0);
  EXPECT_EQ(b.daemon.fsync_ms.value_or(0), 1000);
}

// Fig. 2 orientations built independently: IA = F_E turned by alpha about z_E, then by +90 deg
// about the new IRA (XRA comes up); PA and OA are the same with the case axes relabelled
// cyclically (IRA->XRA->YRA), which a permutation of rows expresses.
TEST(SlotOrientation, MatchesComposedRotationsAndAlphaToVibrationAxis) {
  const double alpha = inertia::deg_to_rad(25.0);
  const Eigen::Matrix3d ia = inertia::frames::frame_rotation(Eigen::Vector3d::UnitX(), inertia::kPi / 2) *
                             inertia::frames::frame_rotation(Eigen::Vector3d::UnitZ(), alpha);
  Eigen::Matrix3d cycle;   // row r of the result = row (r - 1) of the input: IRA->XRA->YRA
  cycle << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  const Eigen::Matrix3d expected[] = {ia, cycle * ia, cycle * cycle * ia};
  const Orientation o[] = {Orientation::IA, Orientation::PA, Orientation::OA};
  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE(k);
    const Eigen::Matrix3d m = slot_orientation(o[k], alpha);
    EXPECT_TRUE(inertia::frames::is_rotation(m, 1e-12));
    EXPECT_LT((m - expected[k]).cwiseAbs().maxCoeff(), 1e-15);
    // Rows are the case axes in F_E: axis k at alpha from the vibration axis x_E, axis k+1 up.
    const Eigen::Vector3d axis_k = m.row(k).transpose();
    EXPECT_NEAR(inertia::frames::axis_angle_between(axis_k, Eigen::Vector3d::UnitX()), alpha, 1e-14);
    EXPECT_NEAR(m(( k + 1) % 3, 2), 1.0, 1e-15);
  }
  // The OA orientation puts IRA up (the paper's third configuration excites PA and OA).
  EXPECT_NEAR(slot_orientation(Orientation::OA, alpha)(0, 2), 1.0, 1e-15);
}

TEST_F(TempFiles, MinimalLoadsWithDefaults) {
  const BenchConfig b = load_bench_config(write("bench.toml", kMinimal));
  EXPECT_NEAR(b.alpha_rad, inertia::deg_to_rad(25.0), 1e-15);
  EXPECT_EQ(b.seed, 1u);
  ASSERT_EQ(b.cases.size(), 1u);
  EXPECT_DOUBLE_EQ(b.cases[0].phases[0].ramp_cycles, 1.0);
  EXPECT_NE(b.sensors[0].seed, 0u);
}

TEST_F(TempFiles, AnAgingSensorsTruthDriftsByCalibration) {
  const std::string aged = replace(kMinimal, "type = \"accelerometer\"\n",
                                   "type = \"accelerometer\"\ncalibration = 3\n[sensor.truth]\nk_b = 4e-3\n[sensor.aging]\nk_b = 1e-4\n");
  const BenchConfig b = load_bench_config(write("aged.toml", aged));
  ASSERT_EQ(b.sensors[0].truth.size(), 1u);
  EXPECT_EQ(b.sensors[0].calibration, 3);
  EXPECT_DOUBLE_EQ(b.sensors[0].truth[0].values[0], 4e-3 + 3 * 1e-4);
  // A drift of a value the truth does not give has nothing to age.
  const InputError e = error_of(replace(kMinimal, "type = \"accelerometer\"\n",
                                        "type = \"accelerometer\"\ncalibration = 1\n[sensor.aging]\nk_i = 1e-4\n"));
  EXPECT_NE(std::string(e.what()).find("ages a scalar of [sensor.truth]"), std::string::npos) << e.what();
}

TEST_F(TempFiles, SyntaxErrorNamesFileLineColumn) {
  fs::path file;
  const InputError e = error_of(replace(kMinimal, "sample_rate_hz = 1000.0", "sample_rate_hz = = 1000.0"), &file);
  EXPECT_EQ(e.where().file, file.string());
  EXPECT_EQ(e.where().line, 3u);
  EXPECT_EQ(e.where().column, 18u);   // the second '='
  EXPECT_NE(std::string(e.what()).find("TOML syntax error"), std::string::npos) << e.what();
  EXPECT_EQ(std::string(e.what()).rfind(file.string() + ":3:18: ", 0), 0u) << e.what();
}

TEST_F(TempFiles, WrongTypePointsAtTheValue) {
  const InputError e = error_of(replace(kMinimal, "sample_rate_hz = 1000.0", "sample_rate_hz = \"fast\""));
  EXPECT_EQ(e.where().line, 3u);
  EXPECT_EQ(e.where().column, 18u);
  EXPECT_NE(std::string(e.what()).find("bench.sample_rate_hz must be a number, got string"), std::string::npos)
      << e.what();
}

TEST_F(TempFiles, UnknownKeyIsAnError) {
  const InputError e = error_of(replace(kMinimal, "duration_s = 1.0", "duration_s = 1.0\nfrequncy_hz = 5.0"));
  EXPECT_EQ(e.where().line, 18u);   // the misspelt key, after duration_s on line 17
  EXPECT_EQ(e.where().column, 1u);
  EXPECT_NE(std::string(e.what()).find("unknown key 'case[0].phase[0].frequncy_hz'"), std::string::npos) << e.what();
}

TEST_F(TempFiles, DaemonTableIsOptionalAndStrict) {
  const BenchConfig none = load_bench_config(write("none.toml", kMinimal));
  EXPECT_FALSE(none.daemon.block_ms || none.daemon.fifo_priority || none.daemon.mlock || none.daemon.log_dir);
  const std::string with = std::string(kMinimal) +
                           "\n[daemon]\nblock_ms = 20\nfifo_priority = 50\ncpu_affinity = 0\nmlock = false\n"
                           "rotate_mb = 8\nfsync_ms = 250\nlog_queue = 64\nring_samples = 4096\n"
                           "log_dir = \"/tmp/l\"\nlcm_url = \"memq://\"\n";
  const BenchConfig b = load_bench_config(write("with.toml", with));
  EXPECT_DOUBLE_EQ(*b.daemon.block_ms, 20.0);
  EXPECT_EQ(*b.daemon.fifo_priority, 50);
  EXPECT_EQ(*b.daemon.cpu_affinity, 0);
  EXPECT_FALSE(*b.daemon.mlock);
  EXPECT_DOUBLE_EQ(*b.daemon.rotate_mb, 8.0);
  EXPECT_EQ(*b.daemon.fsync_ms, 250);
  EXPECT_EQ(*b.daemon.log_queue, 64);
  EXPECT_EQ(*b.daemon.ring_samples, 4096);
  EXPECT_EQ(*b.daemon.log_dir, "/tmp/l");
  EXPECT_EQ(*b.daemon.lcm_url, "memq://");
  // Unknown keys are errors here as everywhere (a typo must not fall back to a default).
  const InputError typo = error_of(std::string(kMinimal) + "\n[daemon]\nfifo_priorty = 50\n");
  EXPECT_NE(std::string(typo.what()).find("unknown key 'daemon.fifo_priorty'"), std::string::npos) << typo.what();
  EXPECT_EQ(typo.where().line, 20u);  // the misspelt key: kMinimal has 17 lines, a blank, [daemon]
  // Out of range and wrong types name the key.
  const InputError prio = error_of(std::string(kMinimal) + "\n[daemon]\nfifo_priority = 100\n");
  EXPECT_NE(std::string(prio.what()).find("daemon.fifo_priority"), std::string::npos) << prio.what();
  const InputError block = error_of(std::string(kMinimal) + "\n[daemon]\nblock_ms = 0\n");
  EXPECT_NE(std::string(block.what()).find("daemon.block_ms"), std::string::npos) << block.what();
  const InputError ring = error_of(std::string(kMinimal) + "\n[daemon]\nring_samples = 10\n");
  EXPECT_NE(std::string(ring.what()).find("daemon.ring_samples"), std::string::npos) << ring.what();
  const InputError mlock = error_of(std::string(kMinimal) + "\n[daemon]\nmlock = 1\n");
  EXPECT_NE(std::string(mlock.what()).find("daemon.mlock"), std::string::npos) << mlock.what();
}

TEST_F(TempFiles, CanInvalidRawAndEncoderEdgeLatency) {
  const auto can = [](const std::string& signal_keys) {
    return std::string(kMinimal) + "\n[[can_device]]\nname = \"adc\"\n[[can_device.signal]]\nname = \"x\"\nid = 0x101\n" +
           signal_keys;
  };
  // Absent: every raw value is a reading.
  EXPECT_FALSE(load_bench_config(write("none.toml", can("bit_length = 16\n"))).can_devices[0].signals[0].invalid_raw);
  // A signed code given negative is stored as the signal's raw bits (two's complement, 24 bits).
  const BenchConfig neg = load_bench_config(write("neg.toml", can("bit_length = 24\nsigned = true\ninvalid_raw = -8388608\n")));
  EXPECT_EQ(*neg.can_devices[0].signals[0].invalid_raw, 0x800000u);
  const BenchConfig hex = load_bench_config(write("hex.toml", can("bit_length = 16\ninvalid_raw = 0xFFFF\n")));
  EXPECT_EQ(*hex.can_devices[0].signals[0].invalid_raw, 0xFFFFu);
  // A code the signal cannot carry, or a negative one for an unsigned signal, names the key.
  const InputError wide = error_of(can("bit_length = 16\ninvalid_raw = 0x10000\n"));
  EXPECT_NE(std::string(wide.what()).find("invalid_raw"), std::string::npos) << wide.what();
  const InputError unsig = error_of(can("bit_length = 16\ninvalid_raw = -1\n"));
  EXPECT_NE(std::string(unsig.what()).find("invalid_raw"), std::string::npos) << unsig.what();

  const std::string enc = std::string(kMinimal) +
                          "\n[[gpiod_encoder]]\nname = \"e\"\nline_a = 1\nline_b = 2\nkind = \"linear\"\nresolution = 1e-6\n";
  EXPECT_EQ(load_bench_config(write("enc.toml", enc)).gpiod_encoders[0].edge_latency_ns, 1'000'000);
  EXPECT_EQ(load_bench_config(write("enc5.toml", enc + "edge_latency_ns = 5000000\n")).gpiod_encoders[0].edge_latency_ns,
            5'000'000);
  const InputError late = error_of(enc + "edge_latency_ns = -1\n");
  EXPECT_NE(std::string(late.what()).find("edge_latency_ns"), std::string::npos) << late.what();
}

TEST_F(TempFiles, EncoderWireChoosesTheSimulatorsTransportOnSimulatedBenchesOnly) {
  const std::string enc = std::string(kMinimal) + "\n[linear_encoder]\nresolution_m = 1e-6\n";
  EXPECT_EQ(load_bench_config(write("gpio.toml", enc)).linear_encoder.wire, EncoderWire::Gpio);
  EXPECT_EQ(load_bench_config(write("can.toml", enc + "wire = \"can\"\n")).linear_encoder.wire, EncoderWire::Can);
  const InputError bad = error_of(enc + "wire = \"spi\"\n");
  EXPECT_NE(std::string(bad.what()).find("\"spi\" is not one of: gpio, can"), std::string::npos) << bad.what();
  // A real bench wires its encoder itself; the key would be a promise nothing keeps.
  const InputError real =
      error_of(replace(enc, "sample_rate_hz = 1000.0", "backend = \"real\"\nsample_rate_hz = 1000.0") + "wire = \"can\"\n");
  EXPECT_NE(std::string(real.what()).find("linear_encoder.wire"), std::string::npos) << real.what();
  EXPECT_NE(std::string(real.what()).find("simulated benches"), std::string::npos) << real.what();
  // The flagship bench's MHz encoders go over CAN (config/sim-paper.toml).
  const BenchConfig paper = load_bench_config(kConfigDir / "sim-paper.toml");
  EXPECT_EQ(paper.table_encoder.wire, EncoderWire::Can);
  EXPECT_EQ(paper.linear_encoder.wire, EncoderWire::Can);
}

TEST_F(TempFiles, MissingKeyPointsAtItsTable) {
  const InputError e = error_of(replace(kMinimal, "amplitude_g = 1.0\n", ""));
  EXPECT_EQ(e.where().line, 13u);   // the [[case.phase]] header
  EXPECT_NE(std::string(e.what()).find("missing key 'amplitude_g'"), std::string::npos) << e.what();
}

TEST_F(TempFiles, BadPhaseKindListsTheKinds) {
  const InputError e = error_of(replace(kMinimal, "kind = \"sine\"", "kind = \"vibrate\""));
  EXPECT_EQ(e.where().line, 14u);
  EXPECT_EQ(e.where().column, 8u);
  const std::string what = e.what();
  EXPECT_NE(what.find("\"vibrate\" is not one of: dwell, rotation, sine, random, shock, thermal_step"),
            std::string::npos)
      << what;
}

TEST_F(TempFiles, OutOfRangeAndMisplacedValues) {
  {
    const InputError e = error_of(std::string(kMinimal) + "\n[fixture]\nalpha_deg = 95.0\n");
    EXPECT_EQ(e.where().line, 20u);
    EXPECT_NE(std::string(e.what()).find("fixture.alpha_deg = 95 is outside [0, 90]"), std::string::npos) << e.what();
  }
  {
    const InputError e = error_of(replace(kMinimal, "frequency_hz = 10.0", "frequency_hz = 600.0"));
    EXPECT_EQ(e.where().line, 15u);
    EXPECT_NE(std::string(e.what()).find("Nyquist"), std::string::npos) << e.what();
  }
  {
    const InputError e = error_of(replace(kMinimal, "kind = \"sine\"\nfrequency_hz = 10.0\namplitude_g = 1.0",
                                          "kind = \"rotation\"\naxis = [1, 0, 0]\nrate_deg_s = 10.0"));
    EXPECT_EQ(e.where().line, 14u);
    EXPECT_NE(std::string(e.what()).find("a rotation phase cannot run in a shaker case"), std::string::npos)
        << e.what();
  }
  {
    // A random band too narrow to hold bins at this duration would silently synthesize nothing.
    const InputError e = error_of(replace(kMinimal, "kind = \"sine\"\nfrequency_hz = 10.0\namplitude_g = 1.0",
                                          "kind = \"random\"\nf1_hz = 100.0\nf2_hz = 102.0\ngrms = 1.0"));
    EXPECT_EQ(e.where().line, 16u);
    EXPECT_NE(std::string(e.what()).find("at least 4 frequency bins"), std::string::npos) << e.what();
  }
  {
    const InputError e = error_of(replace(kMinimal, "duration_s = 1.0", "duration_s = 0.0001"));
    EXPECT_EQ(e.where().line, 17u);
    EXPECT_NE(std::string(e.what()).find("shorter than one sample period"), std::string::npos) << e.what();
  }
  {
    const InputError e = error_of(std::string(kMinimal) + "[[monitor]]\nname = \"m1\"\n[[monitor]]\nname = \"m1\"\n");
    EXPECT_EQ(e.where().line, 21u);
    EXPECT_NE(std::string(e.what()).find("duplicate monitor name 'm1'"), std::string::npos) << e.what();
  }
  {
    const InputError e = error_of(replace(kMinimal, "orientation = \"IA\"", "m_ec = [[1, 0, 0], [0, 1, 0], [0, 1, 1]]"));
    EXPECT_EQ(e.where().line, 12u);
    EXPECT_NE(std::string(e.what()).find("must be a rotation"), std::string::npos) << e.what();
  }
}

TEST_F(TempFiles, IncludedPlanAppendsCasesAndReportsItsOwnFile) {
  const fs::path plan = write("plan.toml", R"([[case]]
name = "c2"
kind = "static"
orientation = "PA"
[[case.phase]]
kind = "dwell"
duration_s = 2.0
)");
  const BenchConfig b = load_bench_config(write("bench.toml", "include = [\"plan.toml\"]\n" + std::string(kMinimal)));
  ASSERT_EQ(b.cases.size(), 2u);
  EXPECT_EQ(b.cases[1].name, "c2");
  EXPECT_EQ(b.cases[1].orientation, Orientation::PA);

  write("plan.toml", "[[case]]\nname = \"c2\"\nkind = \"static\"\norientation = \"PA\"\n[[case.phase]]\nkind = \"dwel\"\nduration_s = 2.0\n");
  fs::path file;
  const InputError e = error_of("include = [\"plan.toml\"]\n" + std::string(kMinimal), &file);
  EXPECT_EQ(e.where().file, plan.string());
  EXPECT_EQ(e.where().line, 6u);
  EXPECT_EQ(e.where().column, 8u);
}

TEST_F(TempFiles, SourcesInMemoryLoadAsTheFilesAndKeepTheirErrors) {
  // The daemon publishes bench.sources on INERTIA_BENCH; the analyzer loads them back without
  // the files: the same config, the same positioned errors, and a missing include is an error.
  write("plan.toml", "[[case]]\nname = \"c2\"\nkind = \"static\"\norientation = \"PA\"\n[[case.phase]]\nkind = \"dwell\"\nduration_s = 2.0\n");
  const fs::path bench = write("bench.toml", "include = [\"plan.toml\"]\n" + std::string(kMinimal));
  const BenchConfig disk = load_bench_config(bench);
  ASSERT_EQ(disk.sources.size(), 2u);
  EXPECT_EQ(disk.sources[0].path, bench);
  EXPECT_EQ(disk.sources[1].path.filename(), "plan.toml");
  fs::remove(bench);
  fs::remove(disk.sources[1].path);
  const BenchConfig memory = load_bench_config_from_sources(disk.sources);
  ASSERT_EQ(memory.cases.size(), 2u);
  EXPECT_EQ(memory.cases[1].name, "c2");
  EXPECT_EQ(memory.cases[1].m_ec, disk.cases[1].m_ec);
  EXPECT_EQ(memory.sensors[0].seed, disk.sensors[0].seed);
  EXPECT_EQ(memory.name, disk.name);
  EXPECT_EQ(memory.file, bench);
  ASSERT_EQ(memory.sources.size(), 2u);
  EXPECT_EQ(memory.sources[1].text, disk.sources[1].text);

  std::vector<SourceFile> bad = disk.sources;
  bad[1].text = replace(bad[1].text, "\"dwell\"", "\"dwel\"");
  try {
    (void)load_bench_config_from_sources(bad);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, disk.sources[1].path.string());
    EXPECT_EQ(e.where().line, 6u);
    EXPECT_EQ(e.where().column, 8u);
  }
  try {
    (void)load_bench_config_from_sources({disk.sources[0]});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, bench.string());
    EXPECT_EQ(e.where().line, 1u);
    EXPECT_NE(std::string(e.what()).find("included file"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)load_bench_config_from_sources({}), InputError);
}

TEST_F(TempFiles, MissingFile) {
  try {
    (void)load_bench_config("/nonexistent/bench.toml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "/nonexistent/bench.toml");
    EXPECT_NE(std::string(e.what()).find("not found"), std::string::npos);
  }
}

}  // namespace
