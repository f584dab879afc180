// Speed of compensation (analyzer/compensate), samples per second on one core:
//  - BM_Compensate/linear: a unit-like linear model (bias, scale, the two cross axes, T);
//  - BM_Compensate/nonlinear: the paper's accelerometer model with second-order, cross-coupling,
//    odd-quadratic and temperature terms, input and output lags, and the squares' high pass;
//  - BM_CompensateTriad/linear|nonlinear: three such models along a unit's axes, solved together
//    (unit/unit_inverse.hpp); items are unit samples of three outputs;
//  - BM_CompensateUnit/linear|nonlinear: that triad and three gyroscopes (bias, scale, cross axes,
//    g-sensitivity and T; nonlinear adds w_i^2 and eq. 5's y*T), six unknowns solved together;
//  - BM_GeneratedC/...: the same models' generated C (double), compiled here with cc -O2 and
//    loaded, one call per sample: its ns per sample, and the ratio against InverseModel on the
//    same samples in the same run (ratio_to_analyzer < 1: the C is faster);
//  - BM_GeneratedTriadC/..., BM_GeneratedUnitC/...: the triad and the unit as generated joint C,
//    likewise against JointInverse.
// Items = samples. The heap runs with inertia-analyze's malloc tunables (analyzer/main.cpp:
// freed blocks reused, not returned and faulted in again), so the figures are the compensation's,
// not the kernel's page faults for each call's fresh output. Run: build/bench/bench_compensate
#include <benchmark/benchmark.h>
#include <dlfcn.h>
#include <malloc.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "analyzer/compensate/c_export.hpp"
#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/procedure/model_simulation.hpp"
#include "analyzer/unit/unit_inverse.hpp"

namespace {

using namespace inertia;
using ident::Variable;

constexpr Eigen::Index kSamples = 1 << 18;

// The heap as inertia-analyze sets it up: large blocks from the heap (glibc's largest mmap
// threshold, above one call's output), and nothing returned to the kernel.
[[maybe_unused]] const bool kHeapAsTheAnalyzers = [] {
  return mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1 && mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max()) == 1;
}();

model::ModelFile model_of(bool nonlinear, bool gyro = false) {
  model::ModelFile m;
  m.sensor = gyro ? dataset::SensorKind::Gyroscope : dataset::SensorKind::Accelerometer;
  m.sample_period_s = 1e-3;
  m.output_sd = 2e-4;
  std::vector<std::pair<const char*, double>> terms = {{"1", 3.4e-3}, {"a_i", 0.0877}, {"a_p", 1e-4}, {"a_o", -2e-4}, {"T", 2e-5}};
  if (gyro) {
    terms = {{"1", 0.01}, {"w_i", 1.2}, {"w_p", 0.003}, {"w_o", -0.002}, {"a_i", 2e-4}, {"T", 3e-5}};
    if (nonlinear) terms.insert(terms.end(), {{"w_i^2", 1e-4}, {"y*T", 1e-4}});
  } else if (nonlinear) {
    terms = {{"1", 3.4e-3},     {"a_i", 0.0877},  {"a_i^2", 4e-5},     {"a_p^2", 3e-5},   {"a_i*a_p", 9e-6},
             {"a_i*a_o", 9e-6}, {"a_p*a_o", 7e-6}, {"a_i*abs(a_i)", -2e-5}, {"T", 2e-5},   {"a_i*T", 3e-6},
             {"a_i[k-1]", 4e-3}, {"y[k-1]", 0.3}};
    m.square_highpass_rad_s = 500.0;
  }
  for (const auto& [name, c] : terms) m.terms.push_back({ident::parse_term(name), c, std::nullopt});
  const auto n = static_cast<Eigen::Index>(m.terms.size());
  m.covariance = Eigen::MatrixXd::Identity(n, n) * 1e-12;
  m.range[gyro ? Variable::Wi : Variable::Ai] = {-30.0, 30.0};
  return m;
}

ident::SignalSet record_of(const model::ModelFile& m) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  ident::SignalSet s(kSamples, "bench");
  for (Variable v : {Variable::Ai, Variable::Ap, Variable::Ao, Variable::T, Variable::Wi, Variable::Wp, Variable::Wo}) {
    Eigen::VectorXd x(kSamples);
    double state = 0.0;
    for (Eigen::Index k = 0; k < kSamples; ++k) x(k) = state = 0.99 * state + g(rng);
    s.set(v, x);
  }
  std::vector<ident::Term> terms;
  Eigen::VectorXd theta(static_cast<Eigen::Index>(m.terms.size()));
  for (std::size_t j = 0; j < m.terms.size(); ++j) terms.push_back(m.terms[j].term), theta(Eigen::Index(j)) = m.terms[j].coefficient;
  s.set(Variable::Y, Eigen::VectorXd::Zero(kSamples));
  const Eigen::Index first = ident::first_usable_row(terms);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(kSamples);
  y.tail(kSamples - first) = procedure::simulate_model(terms, theta, s, first, m.square_highpass_rad_s, 1e-3);
  s.set(Variable::Y, y);
  return s;
}

double analyzer_seconds_per_sample(const model::ModelFile& m, const ident::SignalSet& s) {
  const compensate::InverseModel inverse(m);
  const auto start = std::chrono::steady_clock::now();
  benchmark::DoNotOptimize(inverse.compensate(s, 1e-3).value.data());
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / static_cast<double>(kSamples);
}

void BM_Compensate(benchmark::State& state) {
  const model::ModelFile m = model_of(state.range(0) != 0);
  const ident::SignalSet s = record_of(m);
  const compensate::InverseModel inverse(m);
  for (auto _ : state) benchmark::DoNotOptimize(inverse.compensate(s, 1e-3).value.data());
  state.SetItemsProcessed(state.iterations() * kSamples);
  state.SetLabel(state.range(0) ? "nonlinear" : "linear");
}
BENCHMARK(BM_Compensate)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

/// Models of model_of along a unit's axes, each with its own record: three accelerometers, and
/// with `members` 6 three gyroscopes.
struct UnitRecords {
  unit::UnitModel unit;
  std::vector<ident::SignalSet> records;
};
UnitRecords unit_of(bool nonlinear, int members) {
  UnitRecords t;
  t.unit.unit = "imu";
  for (int member = 0; member < members; ++member) {
    const bool gyro = member >= 3;
    model::ModelFile m = model_of(nonlinear, gyro);
    m.unit = "imu";
    m.unit_axis = member % 3;
    m.name = std::string(gyro ? "g" : "a") + static_cast<char>('x' + member % 3);
    t.records.push_back(record_of(m));
    t.unit.members.push_back(std::move(m));
  }
  return t;
}

/// A unit's outputs solved together (unit/unit_inverse.hpp): items are samples of the unit, one
/// per output each. Each member's record is its own, so the cost is the joint Newton's.
void compensate_unit(benchmark::State& state, int members) {
  const UnitRecords unit = unit_of(state.range(0) != 0, members);
  const unit::UnitInverse inverse(unit.unit);
  std::vector<const ident::SignalSet*> pointers;
  for (const ident::SignalSet& r : unit.records) pointers.push_back(&r);
  for (auto _ : state) benchmark::DoNotOptimize(inverse.joint().compensate(pointers, 1e-3).value.data());
  state.SetItemsProcessed(state.iterations() * kSamples);
  state.SetLabel(state.range(0) ? "nonlinear" : "linear");
}
void BM_CompensateTriad(benchmark::State& state) { compensate_unit(state, 3); }
BENCHMARK(BM_CompensateTriad)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
void BM_CompensateUnit(benchmark::State& state) { compensate_unit(state, 6); }
BENCHMARK(BM_CompensateUnit)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

struct Loaded {
  void* library = nullptr;
  void (*init)(void*) = nullptr;
  // The generated function returns a struct; called through a wrapper compiled with it.
  void (*run)(void*, const double*, const double*, long, double*) = nullptr;
};

/// Generated code (prefix "model") with a loop wrapper whose body `call` computes out[k] from
/// model_compensate, compiled with cc -O2 into a shared object in `dir` and loaded.
Loaded compile_and_load(const std::string& header, const std::string& source, const std::string& call,
                        const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "model.h") << header;
  std::ofstream(dir / "model.c") << source
                                 << "\nvoid model_run(model_state* s, const double* inputs, const double* y, long n, double* out) {\n"
                                    "  long k;\n  for (k = 0; k < n; ++k) out[k] = " << call << ";\n}\n"
                                    "void model_init_any(void* s) { model_init((model_state*)s); }\n";
  const std::string command = "cc -std=c99 -O2 -fPIC -shared -I" + dir.string() + " " + (dir / "model.c").string() + " -lm -o " +
                              (dir / "model.so").string();
  Loaded l;
  if (std::system(command.c_str()) != 0) return l;
  l.library = dlopen((dir / "model.so").c_str(), RTLD_NOW);
  if (l.library == nullptr) return l;
  l.init = reinterpret_cast<void (*)(void*)>(dlsym(l.library, "model_init_any"));
  l.run = reinterpret_cast<void (*)(void*, const double*, const double*, long, double*)>(dlsym(l.library, "model_run"));
  return l;
}

/// Generates the model's C, compiles it into a shared object and loads it.
Loaded load_generated(const model::ModelFile& m, const std::filesystem::path& dir, std::vector<ident::Variable>& inputs) {
  const compensate::CSource c = compensate::generate_c(m, "model", compensate::CPrecision::Double);
  inputs = c.inputs;
  return compile_and_load(c.header, c.source, "model_compensate(s, inputs + k * MODEL_INPUTS, y[k]).value", dir);
}

void BM_GeneratedC(benchmark::State& state) {
  const model::ModelFile m = model_of(state.range(0) != 0);
  const ident::SignalSet s = record_of(m);
  std::vector<ident::Variable> inputs;
  const Loaded l = load_generated(m, std::filesystem::temp_directory_path() / ("inertia-bench-c-" + std::to_string(state.range(0))), inputs);
  if (l.run == nullptr || l.init == nullptr) {
    state.SkipWithError("cc or dlopen failed");
    return;
  }
  std::vector<double> in(static_cast<std::size_t>(kSamples) * inputs.size()), out(static_cast<std::size_t>(kSamples));
  for (Eigen::Index k = 0; k < kSamples; ++k) {
    for (std::size_t i = 0; i < inputs.size(); ++i) in[std::size_t(k) * inputs.size() + i] = s.get(inputs[i])(k);
  }
  alignas(64) unsigned char memory[4096];
  for (auto _ : state) {
    l.init(memory);
    l.run(memory, in.data(), s.get(Variable::Y).data(), kSamples, out.data());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * kSamples);
  // The peer in the same run: InverseModel on the same samples, and the C once more just after.
  const double analyzer = analyzer_seconds_per_sample(m, s);
  const auto start = std::chrono::steady_clock::now();
  l.init(memory);
  l.run(memory, in.data(), s.get(Variable::Y).data(), kSamples, out.data());
  const double generated = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / kSamples;
  state.counters["ns_per_sample"] = generated * 1e9;
  state.counters["ratio_to_analyzer"] = generated / analyzer;
  state.SetLabel(state.range(0) ? "nonlinear" : "linear");
}
BENCHMARK(BM_GeneratedC)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

/// The triad of BM_CompensateTriad (or the unit of BM_CompensateUnit) as generated joint C
/// (double), one call per unit sample: its ns per sample and the ratio against JointInverse on the
/// same samples in the same run.
void generated_unit_c(benchmark::State& state, int members) {
  const UnitRecords unit = unit_of(state.range(0) != 0, members);
  const unit::UnitInverse inverse(unit.unit);
  const std::vector<ident::SignalSet>& records = unit.records;
  std::vector<const ident::SignalSet*> pointers;
  for (const ident::SignalSet& r : records) pointers.push_back(&r);
  const std::vector<std::string> outputs{"ax", "ay", "az", "gx", "gy", "gz"}, unknowns{"a_x", "a_y", "a_z", "w_x", "w_y", "w_z"};
  const auto count = static_cast<std::ptrdiff_t>(members);
  const compensate::JointCSource c =
      compensate::generate_joint_c(inverse.joint(), std::vector<std::string>(outputs.begin(), outputs.begin() + count),
                                   std::vector<std::string>(unknowns.begin(), unknowns.begin() + count), "model",
                                   compensate::CPrecision::Double, 1e-3);
  const Loaded l = compile_and_load(c.header, c.source,
                                    "model_compensate(s, inputs + k * MODEL_INPUTS, y + " + std::to_string(members) + " * k).value[0]",
                                    std::filesystem::temp_directory_path() /
                                        ("inertia-bench-joint-" + std::to_string(members) + "-" + std::to_string(state.range(0))));
  if (l.run == nullptr || l.init == nullptr) {
    state.SkipWithError("cc or dlopen failed");
    return;
  }
  const auto init = l.init;
  const auto run = l.run;
  const auto outputs_per_sample = static_cast<std::size_t>(members);
  std::vector<double> in(static_cast<std::size_t>(kSamples) * c.inputs.size()), y(static_cast<std::size_t>(kSamples) * outputs_per_sample),
      out(static_cast<std::size_t>(kSamples));
  for (Eigen::Index k = 0; k < kSamples; ++k) {
    for (std::size_t i = 0; i < c.inputs.size(); ++i)
      in[std::size_t(k) * c.inputs.size() + i] = records[c.inputs[i].first].get(c.inputs[i].second)(k);
    for (std::size_t m = 0; m < outputs_per_sample; ++m) y[std::size_t(k) * outputs_per_sample + m] = records[m].get(Variable::Y)(k);
  }
  alignas(64) unsigned char memory[16384];
  for (auto _ : state) {
    init(memory);
    run(memory, in.data(), y.data(), kSamples, out.data());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * kSamples);
  auto start = std::chrono::steady_clock::now();
  benchmark::DoNotOptimize(inverse.joint().compensate(pointers, 1e-3).value.data());
  const double analyzer = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / kSamples;
  start = std::chrono::steady_clock::now();
  init(memory);
  run(memory, in.data(), y.data(), kSamples, out.data());
  const double generated = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / kSamples;
  state.counters["ns_per_sample"] = generated * 1e9;
  state.counters["ratio_to_analyzer"] = generated / analyzer;
  state.SetLabel(state.range(0) ? "nonlinear" : "linear");
}
void BM_GeneratedTriadC(benchmark::State& state) { generated_unit_c(state, 3); }
BENCHMARK(BM_GeneratedTriadC)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
void BM_GeneratedUnitC(benchmark::State& state) { generated_unit_c(state, 6); }
BENCHMARK(BM_GeneratedUnitC)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
