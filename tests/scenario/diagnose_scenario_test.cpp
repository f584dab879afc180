// Scenario tests of the discrepancy workflow: the bench simulator produces data from a
// known truth, diagnose gets the truth's model minus one or two terms, and must name exactly
// what was hidden. The benches use white noise only (pink and brown set to zero) and no case or
// fixture misalignment, so the truth is exactly a model in the library's terms and the noise
// floor is K_i * white_sd_g: the expectations (coefficient within 3 sd, final RMS within 20% of
// the floor, false-alarm rate) are then clean consequences of the statistics, not of model error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <unistd.h>
#include <set>
#include <string>

#include "analyzer/commands/characterize.hpp"
#include "analyzer/commands/noise.hpp"
#include "analyzer/diagnose/discrepancy.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/noise/noise_analysis.hpp"
#include "common/config/bench_config.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/sensor_truth.hpp"
#include "hal/sim/sensors/accelerometer_model_terms.hpp"
#include "hal/sim/simulate.hpp"

namespace inertia::diagnose {
namespace {

constexpr double kWhiteSdG = 1e-4;
constexpr double kScale = 0.86;   // k_i, output unit per g

/// A small shaker bench (2 kHz): the three Fig. 2 orientations, each a dwell, a 40 Hz sine and a
/// random phase, so every pair of axes shares the vibration once.
std::string shaker_bench(const std::string& truth, std::uint64_t seed) {
  std::string s = "[bench]\nname = \"diag-shaker\"\nbackend = \"sim\"\nsample_rate_hz = 2000.0\nt_ref_c = 25.0\nseed = " +
                  std::to_string(seed) + "\n[fixture]\nalpha_deg = 25.0\n";
  s += "[[sensor]]\nname = \"acc\"\ntype = \"accelerometer\"\noutput_unit = \"mA\"\nslot = \"A1\"\nseed = " +
       std::to_string(seed * 7919 + 1) + "\n[sensor.truth]\n" + truth;
  for (const char* o : {"IA", "PA", "OA"}) {
    s += std::string("[[case]]\nname = \"shaker-") + o + "\"\nkind = \"shaker\"\norientation = \"" + o + "\"\n";
    s += "[[case.phase]]\nkind = \"dwell\"\nduration_s = 0.2\n";
    s += "[[case.phase]]\nkind = \"sine\"\nfrequency_hz = 40.0\namplitude_g = 10.0\nramp_cycles = 4.0\nduration_s = 1.0\n";
    s += "[[case.phase]]\nkind = \"random\"\nf1_hz = 20.0\nf2_hz = 500.0\ngrms = 8.0\nramp_s = 0.05\nduration_s = 1.0\n";
  }
  return s;
}

/// The thermal bench of config/sim-thermal.toml, shortened and at 50 Hz, white noise only.
std::string thermal_bench(const std::string& truth, std::uint64_t seed) {
  std::string s = "[bench]\nname = \"diag-thermal\"\nbackend = \"sim\"\nsample_rate_hz = 50.0\nt_ref_c = 25.0\nseed = " +
                  std::to_string(seed) + "\n";
  s += "[fixture.thermal]\nambient_c = 22.0\ninitial_c = 25.0\ntau_s = 300.0\nheat_rate_max_c_per_s = 0.5\n"
       "kp_per_c = 0.2\nki_per_c_s = 0.002\nsensor_noise_sd_c = 0.02\n";
  s += "[[sensor]]\nname = \"acc\"\ntype = \"accelerometer\"\noutput_unit = \"mA\"\nslot = \"A1\"\n[sensor.truth]\n" + truth;
  s += "[[case]]\nname = \"thermal-up\"\nkind = \"thermal\"\nm_ec = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]\n"
       "[[case.phase]]\nkind = \"dwell\"\nduration_s = 60.0\n"
       "[[case.phase]]\nkind = \"thermal_step\"\nsetpoint_c = 40.0\nduration_s = 300.0\n"
       "[[case.phase]]\nkind = \"thermal_step\"\nsetpoint_c = 10.0\nduration_s = 300.0\n";
  s += "[[case]]\nname = \"thermal-down\"\nkind = \"thermal\"\nm_ec = [[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]\n"
       "[[case.phase]]\nkind = \"thermal_step\"\nsetpoint_c = 55.0\nduration_s = 300.0\n"
       "[[case.phase]]\nkind = \"thermal_step\"\nsetpoint_c = 25.0\nduration_s = 300.0\n";
  return s;
}

/// A rate table at 200 Hz with one FOG at the table centre: 90 deg steps about a horizontal axis
/// (the input axis sees +-1 g and 0 g: g-sensitivity shows in the dwells) and constant rates.
std::string gyro_bench(std::uint64_t seed) {
  std::string s = "[bench]\nname = \"diag-gyro\"\nbackend = \"sim\"\nsample_rate_hz = 200.0\nt_ref_c = 25.0\nseed = " +
                  std::to_string(seed) + "\n[fixture]\nalpha_deg = 25.0\n";
  s += "[[sensor]]\nname = \"fog\"\ntype = \"gyroscope\"\noutput_unit = \"rad/s\"\nslot = \"G1\"\n[sensor.truth]\n"
       "s0 = 1.0\nc_i = 1.0005\ndrift_rad_s = 2e-6\nnoise_sd_rad_s = 1e-5\n"
       "g_sens_i_num = [2e-5, 0.0, 0.0]\ng_sens_i_den = [1.0, 0.0, 0.0]\n";
  s += "[table_encoder]\nresolution_rad = 1e-6\n";
  s += "[[case]]\nname = \"multipoint\"\nkind = \"rotation_table\"\nm_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n";
  for (int i = 0; i < 4; ++i) {
    s += "[[case.phase]]\nkind = \"dwell\"\nduration_s = 3.0\n"
         "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 1.0, 0.0]\nangle_deg = 90.0\nduration_s = 2.0\n";
  }
  s += "[[case]]\nname = \"rates\"\nkind = \"rotation_table\"\nm_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n";
  for (const char* rate : {"30.0", "-30.0", "90.0", "-90.0"}) {
    s += std::string("[[case.phase]]\nkind = \"rotation\"\naxis = [1.0, 0.0, 0.0]\nrate_deg_s = ") + rate +
         "\nduration_s = 3.0\n[[case.phase]]\nkind = \"dwell\"\nduration_s = 1.0\n";
  }
  return s;
}

/// White noise only (unless `pink_sd_g` > 0), no high-pass quadratics (their static stand-in
/// a_j^2 is not exact).
std::string truth_fields(const std::string& extra, double pink_sd_g = 0.0) {
  return "k_i = 0.86\nk_b = 4e-3\nk_ii = 0.0\nk_pp = 0.0\nk_oo = 0.0\nwhite_sd_g = 1e-4\npink_sd_g = " +
         std::to_string(pink_sd_g) + "\nbrown_sd_g = 0.0\nb_ii_rad_s = 100.0\nb_pp_rad_s = 100.0\nb_oo_rad_s = 100.0\n" + extra;
}

struct Scenario {
  dataset::Dataset data;
  model::ModelFile model;                  // truth minus the hidden terms
  std::map<std::string, double> hidden;    // canonical term -> true coefficient
};

Scenario make_scenario(const std::string& bench_text, const std::set<std::string>& hide,
                       std::optional<double> square_highpass_rad_s = std::nullopt) {
  static int counter = 0;
  const std::filesystem::path file = std::filesystem::temp_directory_path() /
                                     ("diag_scenario_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + ".toml");
  std::ofstream(file) << bench_text;
  const config::BenchConfig bench = config::load_bench_config(file);
  std::filesystem::remove(file);
  const sim::BenchSimulation simulation = sim::simulate_bench(bench);
  Scenario s;
  s.data = sim::sensor_dataset(bench, simulation, 0);
  const auto& params = std::get<sim::AccelerometerParams>(simulation.params[0]);
  s.model.sensor = dataset::SensorKind::Accelerometer;
  s.model.m_cs = simulation.cases[0].sensors[0].m_cs;
  s.model.white_sd = params.k_i * params.white_sd_g;
  s.model.square_highpass_rad_s = square_highpass_rad_s;
  for (const auto& [name, coefficient] : sim::accelerometer_model_terms(params)) {
    const std::string canonical = ident::parse_term(name).to_string();
    if (hide.count(canonical)) {
      s.hidden[canonical] = coefficient;
    } else {
      s.model.terms.push_back({ident::parse_term(name), coefficient, std::nullopt});
    }
  }
  EXPECT_EQ(s.hidden.size(), hide.size()) << "a hidden term is not in the truth";
  return s;
}

Scenario make_gyro_scenario(std::uint64_t seed, const std::set<std::string>& hide) {
  const std::filesystem::path file = std::filesystem::temp_directory_path() /
                                     ("diag_gyro_" + std::to_string(::getpid()) + "_" + std::to_string(seed) + ".toml");
  std::ofstream(file) << gyro_bench(seed);
  const config::BenchConfig bench = config::load_bench_config(file);
  std::filesystem::remove(file);
  const sim::BenchSimulation simulation = sim::simulate_bench(bench);
  Scenario s;
  s.data = sim::sensor_dataset(bench, simulation, 0);
  const auto& params = std::get<sim::FogParams>(simulation.params[0]);
  s.model.sensor = dataset::SensorKind::Gyroscope;
  s.model.m_cs = simulation.cases[0].sensors[0].m_cs;
  s.model.white_sd = params.noise_sd_rad_s / params.s0;
  for (const auto& [key, value] : sim::model_terms(params, nullptr)) {
    const std::string canonical = ident::parse_term(key.str()).to_string();
    const double coefficient = value.value<double>().value_or(std::nan(""));
    if (hide.count(canonical)) {
      s.hidden[canonical] = coefficient;
    } else {
      s.model.terms.push_back({ident::parse_term(canonical), coefficient, std::nullopt});
    }
  }
  EXPECT_EQ(s.hidden.size(), hide.size()) << "a hidden term is not in the truth";
  return s;
}

/// The figures, for the log: what was found against truth, and the RMS before and after.
void print_figures(const char* name, const Scenario& s, const DiagnoseResult& r) {
  Eigen::Index rows = 0;
  for (const dataset::CaseData& c : s.data.cases) rows += c.size();
  std::cout << "[ " << name << " ] " << rows << " rows, RMS baseline " << r.steps.front().overall << " final "
            << r.steps.back().overall << " floor " << *s.model.white_sd << '\n';
  for (const Finding& f : r.findings) {
    const auto it = s.hidden.find(f.term);
    std::cout << "    found " << f.term << " (" << f.effect << ") " << f.coefficient << " +- " << f.std << " t " << f.t
              << " truth " << (it == s.hidden.end() ? std::nan("") : it->second) << " in " << f.where_case << "/"
              << f.where_phase << '\n';
  }
}

/// The checks every single-effect scenario shares.
void expect_found_first(const Scenario& s, const DiagnoseResult& r, const std::string& term) {
  ASSERT_FALSE(r.findings.empty()) << "nothing found; baseline RMS " << r.steps.front().overall;
  const Finding& f = r.findings.front();
  EXPECT_EQ(f.term, term);
  const double truth = s.hidden.at(term);
  EXPECT_LT(std::abs(f.coefficient - truth), 3.0 * f.std)
      << f.term << ": " << f.coefficient << " +- " << f.std << " vs truth " << truth;
  const double floor = kScale * kWhiteSdG;
  EXPECT_LT(std::abs(r.steps.back().overall / floor - 1.0), 0.2)
      << "final RMS " << r.steps.back().overall << " vs noise floor " << floor;
  // The gap must have shrunk: the baseline is well above the floor.
  EXPECT_GT(r.steps.front().overall, 1.5 * floor);
}

/// The checks of the several-effect scenarios: every hidden term is in the final augmented model
/// (all refitted together) within 3 of its sd of truth, and the final RMS is within 20% of the floor.
void expect_final_model_holds_the_hidden_terms(const Scenario& s, const DiagnoseResult& r) {
  for (const auto& [term, truth] : s.hidden) {
    const ident::Term t = ident::parse_term(term);
    const auto it = std::find_if(r.final_model.terms.begin(), r.final_model.terms.end(),
                                 [&](const model::ModelTerm& m) { return m.term == t; });
    ASSERT_NE(it, r.final_model.terms.end()) << term;
    ASSERT_TRUE(it->std.has_value());
    EXPECT_LT(std::abs(it->coefficient - truth), 3.0 * *it->std) << term << ": " << it->coefficient << " +- " << *it->std
                                                                 << " vs " << truth;
  }
  EXPECT_LT(std::abs(r.steps.back().overall / (kScale * kWhiteSdG) - 1.0), 0.2);
}

/// One effect hidden on the shaker bench: found first and alone, under its physical name.
void expect_single_effect(const Scenario& s, const char* label, const std::string& term, const std::string& effect) {
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures(label, s, r);
  expect_found_first(s, r, term);
  EXPECT_EQ(r.findings.size(), 1U);
  EXPECT_EQ(r.findings.front().effect, effect);
}

TEST(DiagnoseScenario, HiddenCrossCouplingFoundUnderVibration) {
  const Scenario s = make_scenario(shaker_bench(truth_fields("k_ip = 2e-3\nk_io = 1e-3\nk_po = 1e-3\n"), 11), {"a_i*a_p"});
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures("cross-coupling", s, r);
  expect_found_first(s, r, "a_i*a_p");
  EXPECT_EQ(r.findings.size(), 1U) << "second finding: " << (r.findings.size() > 1 ? r.findings[1].term : "");
  EXPECT_EQ(r.findings.front().effect, "cross-coupling (vibropendulous)");
  // It shows only under vibration: the dwell phases are within the noise before and after.
  for (const SegmentStats& seg : r.steps.front().segments) {
    if (seg.phase == "dwell" || seg.phase == "static") {
      EXPECT_FALSE(seg.excess) << seg.phase;
    }
  }
  EXPECT_NE(r.findings.front().where_phase, "static");   // the simulator labels dwells "static"
}

TEST(DiagnoseScenario, HiddenOddQuadraticFound) {
  expect_single_effect(make_scenario(shaker_bench(truth_fields("k_oq = 2e-5\n"), 12), {"a_i*abs(a_i)"}), "odd quadratic",
                       "a_i*abs(a_i)", "odd quadratic");
}

TEST(DiagnoseScenario, HiddenBiasTemperatureCoefficientFoundInThermalSteps) {
  const Scenario s = make_scenario(thermal_bench(truth_fields("bias_tc_g_per_degc = 5e-5\n"), 3), {"T"});
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-thermal");
  print_figures("bias temperature coefficient", s, r);
  expect_found_first(s, r, "T");
  EXPECT_EQ(r.findings.size(), 1U);
  EXPECT_EQ(r.findings.front().effect, "bias temperature coefficient");
  EXPECT_NE(r.findings.front().where_phase, "static");   // the simulator labels dwells "static"
}

TEST(DiagnoseScenario, TwoHiddenEffectsBothFound) {
  const Scenario s =
      make_scenario(shaker_bench(truth_fields("k_ip = 2e-3\nk_oq = 2e-5\n"), 13), {"a_i*a_p", "a_i*abs(a_i)"});
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures("two hidden", s, r);
  ASSERT_EQ(r.findings.size(), 2U);
  for (const Finding& f : r.findings) {
    ASSERT_TRUE(s.hidden.count(f.term)) << "found " << f.term;
  }
  EXPECT_NE(r.findings[0].term, r.findings[1].term);
  // The coefficients of the final, augmented model (both re-estimated together).
  expect_final_model_holds_the_hidden_terms(s, r);
}

/// The squares through eq. 12's high pass (corner 300 rad/s on all three axes): the model given
/// has a_p^2, a_o^2 and the corner, and lacks a_i^2; the library's a_i^2 passes the model's high
/// pass, so the dynamic quadratic is named with its high-frequency gain.
std::string highpass_truth(const std::string& extra) {
  return "k_i = 0.86\nk_b = 4e-3\nk_ii = 6e-5\nk_pp = 4e-5\nk_oo = 3e-5\nwhite_sd_g = 1e-4\npink_sd_g = 0.0\n"
         "brown_sd_g = 0.0\nb_ii_rad_s = 300.0\nb_pp_rad_s = 300.0\nb_oo_rad_s = 300.0\n" + extra;
}

TEST(DiagnoseScenario, HiddenHighPassSquareFound) {
  const Scenario s = make_scenario(shaker_bench(highpass_truth("k_ip = 1e-3\n"), 14), {"a_i^2"}, 300.0);
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures("high-pass square", s, r);
  expect_found_first(s, r, "a_i^2");
  EXPECT_EQ(r.findings.size(), 1U);
  EXPECT_EQ(r.findings.front().effect, "second-order nonlinearity");
  EXPECT_TRUE(r.case_misalignments.empty());
}

/// A datasheet model: bias, scale factor and cross-coupling only, no squares and no high pass,
/// while the sensor's squares act through eq. 12's s / (s + 300 rad/s). Offered only as static
/// squares they fit the wrong shape, so diagnose estimates the corner once a square wins a step;
/// all three are then named, each with its high-frequency gain, and the corner goes to the model.
TEST(DiagnoseScenario, DatasheetModelGetsTheSquaresAndTheirHighPass) {
  const Scenario s = make_scenario(shaker_bench(highpass_truth("k_ip = 1e-3\n"), 17), {"a_i^2", "a_p^2", "a_o^2"});
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures("datasheet model", s, r);
  ASSERT_TRUE(r.estimated_square_corner_rad_s.has_value());
  std::cout << "    corner " << *r.estimated_square_corner_rad_s << " rad/s, truth 300\n";
  ASSERT_TRUE(r.final_model.square_highpass_rad_s.has_value());
  EXPECT_EQ(*r.final_model.square_highpass_rad_s, *r.estimated_square_corner_rad_s);
  std::set<std::string> found;
  for (const Finding& f : r.findings) found.insert(f.term);
  EXPECT_EQ(found, (std::set<std::string>{"a_i^2", "a_p^2", "a_o^2"}));
  expect_final_model_holds_the_hidden_terms(s, r);
}

/// Two mountings on the shaker: IA and PA on one fixture, OA on a second one that is turned by
/// 0.5 deg about the case Y axis. The model (truth, with the first fixture's m_cs) lacks nothing;
/// the only discrepancy is the second fixture's rotation, and diagnose must report it as a case
/// misalignment of that mounting (not as a sensor term), with the angle within 3 sd.
TEST(DiagnoseScenario, MountingRotationNamedAsCaseMisalignment) {
  std::string bench = shaker_bench(truth_fields("k_ip = 1e-3\n"), 18);
  const std::string oa = "orientation = \"OA\"\n";
  bench.replace(bench.find(oa), oa.size(), oa + "mounting = \"fixture-2\"\n"
                "case_misalignment = { axis = [0.0, 1.0, 0.0], angle_deg = 0.5 }\n");
  for (const char* o : {"IA", "PA"}) {
    const std::string line = std::string("orientation = \"") + o + "\"\n";
    bench.replace(bench.find(line), line.size(), line + "mounting = \"fixture-1\"\n");
  }
  const Scenario s = make_scenario(bench, {});
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures("mounting rotation", s, r);
  for (const Finding& f : r.case_misalignments) {
    std::cout << "    case misalignment " << f.mounting << " about " << "xyz"[f.axis] << ": " << f.angle_deg << " +- "
              << f.angle_std_deg << " deg\n";
  }
  EXPECT_TRUE(r.findings.empty()) << "found a sensor term: " << r.findings.front().term;
  ASSERT_EQ(r.case_misalignments.size(), 1U);
  const Finding& m = r.case_misalignments.front();
  EXPECT_EQ(m.mounting, "fixture-2");
  EXPECT_EQ(m.axis, 1);
  EXPECT_LT(std::abs(m.angle_deg - 0.5), 3.0 * m.angle_std_deg) << m.angle_deg << " +- " << m.angle_std_deg;
  EXPECT_LT(std::abs(r.steps.back().overall / (kScale * kWhiteSdG) - 1.0), 0.2);
}

TEST(DiagnoseScenario, HiddenRectificationFound) {
  expect_single_effect(make_scenario(shaker_bench(truth_fields("k_a = 5e-5\n"), 15), {"abs(a_i)"}), "rectification",
                       "abs(a_i)", "rectification");
}

/// Three at once, one of them dynamic: cross-coupling, rectification and the high-pass a_i^2.
TEST(DiagnoseScenario, ThreeHiddenEffectsAllFound) {
  const Scenario s = make_scenario(shaker_bench(highpass_truth("k_ip = 2e-3\nk_a = 5e-5\n"), 16),
                                   {"a_i*a_p", "abs(a_i)", "a_i^2"}, 300.0);
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures("three hidden", s, r);
  ASSERT_EQ(r.findings.size(), 3U);
  std::set<std::string> found;
  for (const Finding& f : r.findings) found.insert(f.term);
  EXPECT_EQ(found.size(), 3U);
  for (const auto& [term, truth] : s.hidden) EXPECT_TRUE(found.count(term)) << term;
  expect_final_model_holds_the_hidden_terms(s, r);
}

TEST(DiagnoseScenario, HiddenGyroGSensitivityFound) {
  const Scenario s = make_gyro_scenario(21, {"a_i"});
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-gyro");
  print_figures("gyro g-sensitivity", s, r);
  ASSERT_FALSE(r.findings.empty());
  const Finding& f = r.findings.front();
  EXPECT_EQ(f.term, "a_i");
  EXPECT_EQ(f.effect, "g-sensitivity");
  EXPECT_LT(std::abs(f.coefficient - s.hidden.at("a_i")), 3.0 * f.std) << f.coefficient << " +- " << f.std;
  EXPECT_EQ(r.findings.size(), 1U);
  const double floor = *s.model.white_sd;
  EXPECT_LT(std::abs(r.steps.back().overall / floor - 1.0), 0.2) << r.steps.back().overall << " vs " << floor;
  EXPECT_GT(r.steps.front().overall, 1.5 * floor);
}

/// Nothing hidden: at most 5% of seeds may report a finding (alpha = 0.05 family-wise per step).
/// Over 20 seeds that allows one. Seeds first_seed + 1 .. first_seed + 20.
void expect_false_alarm_rate(double pink_sd_g, int first_seed, const char* label) {
  int alarms = 0;
  std::string what;
  constexpr int kSeeds = 20;
  for (int seed = first_seed + 1; seed <= first_seed + kSeeds; ++seed) {
    const Scenario s = make_scenario(shaker_bench(truth_fields("k_ip = 2e-3\nk_oq = 2e-5\n", pink_sd_g), seed), {});
    const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
    if (!r.findings.empty()) {
      ++alarms;
      what += " seed " + std::to_string(seed) + ": " + r.findings.front().term;
    }
  }
  std::cout << "[ " << label << " ] false alarms " << alarms << " of " << kSeeds << " seeds" << what << '\n';
  EXPECT_LE(alarms, 1) << what;
}

TEST(DiagnoseScenario, ControlNothingHiddenFalseAlarmRate) { expect_false_alarm_rate(0.0, 100, "control"); }

}  // namespace
}  // namespace inertia::diagnose

namespace inertia::diagnose {
namespace {

/// Honest standard deviations: over seeds, z = (estimate - truth) / std must scatter like N(0, 1).
/// Under white noise and under pink noise five times stronger than the white (where ordinary
/// least squares would understate the sd several-fold; the AR prewhitening must correct it).
/// A weak effect (t of order 10-30), so the 3-sd criterion of the other tests is not trivially met.
/// Bounds: with 20 seeds, the sample sd of z lies in [0.6, 1.45] with probability ~99% when the
/// stated sd is right (chi-square, 19 dof).
void expect_honest_std(double pink_sd_g, const char* label) {
  constexpr int kSeeds = 20;
  std::vector<double> z;
  int found_first = 0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const Scenario s = make_scenario(shaker_bench(truth_fields("k_ip = 2e-3\nk_oq = 1e-6\n", pink_sd_g), 300 + seed),
                                     {"a_i*abs(a_i)"});
    const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
    if (r.findings.empty() || r.findings.front().term != "a_i*abs(a_i)") {
      std::cout << "    seed " << 300 + seed << ": first finding "
                << (r.findings.empty() ? std::string("none") : r.findings.front().term) << '\n';
      continue;
    }
    std::cout << "    seed " << 300 + seed << ": t " << r.findings.front().t << " AR order " << r.findings.front().ar_order << '\n';
    ++found_first;
    z.push_back((r.findings.front().coefficient - s.hidden.at("a_i*abs(a_i)")) / r.findings.front().std);
  }
  double mean = 0.0, ss = 0.0;
  for (double v : z) mean += v / static_cast<double>(z.size());
  for (double v : z) ss += (v - mean) * (v - mean);
  const double sd = std::sqrt(ss / static_cast<double>(z.size() - 1));
  std::cout << "[ " << label << " ] found first in " << found_first << " of " << kSeeds << " seeds; z mean " << mean
            << " sd " << sd << '\n';
  EXPECT_EQ(found_first, kSeeds);
  ASSERT_GE(z.size(), 10U);
  EXPECT_GT(sd, 0.6);
  EXPECT_LT(sd, 1.45);
  EXPECT_LT(std::abs(mean), 3.0 / std::sqrt(static_cast<double>(z.size())));   // 3 sd of the mean of N(0, 1)
}

TEST(DiagnoseScenario, WeakOddQuadraticHonestStdWhiteNoise) { expect_honest_std(0.0, "coverage, white noise"); }
TEST(DiagnoseScenario, WeakOddQuadraticHonestStdPinkNoise) { expect_honest_std(5e-4, "coverage, pink noise"); }

/// Control under pink noise: the prewhitened t-test must keep the false-alarm rate too.
TEST(DiagnoseScenario, ControlPinkNoiseFalseAlarmRate) { expect_false_alarm_rate(5e-4, 500, "control, pink noise"); }

/// The bench's pink noise (five times its white) and a model whose [noise] holds the
/// terms `inertia-analyze noise` estimates on a 30 s static run of the same sensor (a run of its
/// own, its own seed), the determined ones with their sd ([noise.std]). With the white noise alone every seed's low bands, its segments and its
/// condition bins read as excess (the control, asserted so the test can fail). With the law, each
/// family is a 5 % family-wise test per seed: the issue asks for no band alarm in 19 of 20 seeds.
/// Seen (2026-11-27): band alarms in 1 of 20 seeds (seed 1612, shaker-OA 0-3.9 Hz, power x4.2 on
/// 8 dof, p 4e-5), no segment or condition alarm. Before the law's own N was used (white_sd in
/// its place beside the law's Q), 2 of 20: seed 1610 read 250-500 Hz at x1.18 on 862 dof.
void use_estimated_noise_terms(std::uint64_t seed, double pink_sd_g, model::ModelFile& model) {
  std::string bench = "[bench]\nname = \"diag-static\"\nbackend = \"sim\"\nsample_rate_hz = 2000.0\nt_ref_c = 25.0\nseed = " +
                      std::to_string(seed + 100000) + "\n";
  bench += "[[sensor]]\nname = \"acc\"\ntype = \"accelerometer\"\noutput_unit = \"mA\"\nslot = \"A1\"\nseed = " +
           std::to_string(seed * 7919 + 2) + "\n[sensor.truth]\n" + truth_fields("", pink_sd_g);
  bench += "[[case]]\nname = \"static\"\nkind = \"static\"\norientation = \"IA\"\n[[case.phase]]\nkind = \"dwell\"\nduration_s = 30.0\n";
  const noise::NoiseAnalysis a = noise::analyse_noise(make_scenario(bench, {}).data);
  ASSERT_TRUE(a.fit.has_value()) << a.fit_error;
  // As `noise` and characterize write them: the determined terms, each with its sd.
  commands::noise_terms_into(a, model);
}

int excess_bands(const Location& location) {
  int n = 0;
  for (const CaseBands& cb : location.bands)
    for (const BandTest& b : cb.bands) n += b.excess ? 1 : 0;
  return n;
}

int excess_conditions(const Location& location) {
  int n = 0;
  for (const ConditionBin& b : location.conditions) n += b.excess ? 1 : 0;
  return n;
}

int excess_segments(const ResidualSummary& summary) {
  int n = 0;
  for (const SegmentStats& s : summary.segments) n += s.excess ? 1 : 0;
  return n;
}

TEST(DiagnoseScenario, PinkNoiseWithItsEstimatedTermsRaisesNoBandAlarm) {
  constexpr double kPink = 5e-4;
  constexpr int kSeeds = 20;
  struct Count {
    int bands = 0, conditions = 0, segments = 0;
    void add(const DiagnoseResult& r) {
      bands += excess_bands(r.location_before) > 0 ? 1 : 0;
      conditions += excess_conditions(r.location_before) > 0 ? 1 : 0;
      segments += excess_segments(r.steps.front()) > 0 ? 1 : 0;
    }
  } with_terms, white_only;
  for (int seed = 1601; seed < 1601 + kSeeds; ++seed) {
    Scenario s = make_scenario(shaker_bench(truth_fields("k_ip = 2e-3\nk_oq = 2e-5\n", kPink), seed), {});
    const DiagnoseResult plain = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
    use_estimated_noise_terms(seed, kPink, s.model);
    const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
    with_terms.add(r);
    white_only.add(plain);
    std::cout << "[ pink, estimated terms ] seed " << seed << ":";
    for (std::size_t t = 0; t < s.model.noise.values.size(); ++t)
      std::cout << ' ' << model::ModelFile::NoiseTerms::kKeys[t] << ' ' << s.model.noise.values[t].value_or(0.0);
    std::cout << "; alarms: bands " << excess_bands(r.location_before) << ", conditions " << excess_conditions(r.location_before)
              << ", segments " << excess_segments(r.steps.front()) << " (white only " << excess_bands(plain.location_before)
              << ", " << excess_conditions(plain.location_before) << ", " << excess_segments(plain.steps.front()) << "); "
              << r.location_before.verdict << '\n';
  }
  std::cout << "[ pink, estimated terms ] seeds with an alarm: bands " << with_terms.bands << ", conditions "
            << with_terms.conditions << ", segments " << with_terms.segments << " of " << kSeeds << " (white noise only: "
            << white_only.bands << ", " << white_only.conditions << ", " << white_only.segments << ")\n";
  EXPECT_LE(with_terms.bands, 1);
  EXPECT_LE(with_terms.conditions, 1);
  EXPECT_LE(with_terms.segments, 1);
  EXPECT_GE(white_only.bands, kSeeds / 2) << "the control: without the terms the pink noise must read as excess";
  EXPECT_GE(white_only.conditions, kSeeds / 2);
  EXPECT_GE(white_only.segments, kSeeds / 2);
}

/// A model characterize made of its own bench names nothing: sim-thermal's flicker noise made an
/// output lag y[k-1] fit the noise's colour one step ahead (0.628 at t 446 on the shipped seed),
/// while the free run's RMS stayed 0.00019337 mA; a finding must now improve the free run as much
/// as its one-step test says.
TEST(DiagnoseScenario, ACharacterizedThermalModelOnItsOwnDataNamesNothing) {
  const config::BenchConfig bench =
      config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-thermal.toml");
  const sim::BenchSimulation sim = sim::simulate_bench(bench);
  const dataset::Dataset data = sim::sensor_dataset(bench, sim, 0);
  const procedure::PipelineResult characterized =
      procedure::run_pipeline(data, commands::pipeline_options(commands::CharacterizeOptions{}), "sim-thermal");
  std::optional<noise::NoiseAnalysis> noise;
  std::string no_noise;
  const model::ModelFile model =
      commands::characterized_model(characterized, data, procedure::batch_verification(data, characterized), noise, no_noise);
  ASSERT_TRUE(noise.has_value()) << no_noise;
  const DiagnoseResult r = diagnose(data, model, DiagnoseOptions{}, "sim-thermal");
  for (const Finding& f : r.findings) ADD_FAILURE() << "named " << f.term << " at t " << f.t;
}

TEST(DiagnoseScenario, PinkNoiseWithItsEstimatedTermsStillFindsAHiddenTerm) {
  constexpr double kPink = 5e-4;
  Scenario s = make_scenario(shaker_bench(truth_fields("k_ip = 2e-3\nk_oq = 2e-5\n", kPink), 1701), {"a_i*a_p"});
  use_estimated_noise_terms(1701, kPink, s.model);
  const DiagnoseResult r = diagnose(s.data, s.model, DiagnoseOptions{}, "diag-shaker");
  print_figures("pink, estimated terms, a_i*a_p hidden", s, r);
  ASSERT_FALSE(r.findings.empty());
  EXPECT_EQ(r.findings.front().term, "a_i*a_p");
  EXPECT_LT(std::abs(r.findings.front().coefficient - s.hidden.at("a_i*a_p")), 3.0 * r.findings.front().std);
  EXPECT_GT(excess_bands(r.location_before), 0) << "the hidden term's excess is in the bands";
}

}  // namespace
}  // namespace inertia::diagnose
