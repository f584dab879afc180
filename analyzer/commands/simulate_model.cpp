#include "analyzer/commands/simulate_model.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <toml++/toml.h>

#include <cmath>
#include <fstream>
#include <random>

#include "analyzer/commands/truth_file.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/noise/noise_fit.hpp"
#include "analyzer/procedure/model_simulation.hpp"
#include "common/config/bench_config.hpp"
#include "common/dataset/dataset.hpp"
#include "common/input_error.hpp"
#include "hal/sim/simulate.hpp"

namespace inertia::commands {
namespace {

toml::array dcm_array(const frames::Dcm& m) {
  toml::array rows;
  for (Eigen::Index r = 0; r < 3; ++r) rows.push_back(toml::array{m(r, 0), m(r, 1), m(r, 2)});
  return rows;
}

// One sensor's folder: its output from `model`, its truth.toml the model's.
void apply_model(const std::filesystem::path& dir, const std::filesystem::path& model_file, std::ostream& summary) {
  const model::ModelFile model = model::read_model(model_file);
  dataset::Dataset data = dataset::read_dataset(dir);
  if (model.sensor != data.sensor)
    throw InputError(fmt::format("{}: a model of an {} for the bench's {} in {}", model_file.string(), dataset::to_string(model.sensor),
                                 dataset::to_string(data.sensor), dir.string()));
  const std::string truth_file = (dir / "truth.toml").string();
  const std::optional<Truth> read = read_truth(dir);
  if (!read) throw InputError(truth_file + ": missing (simulate writes it)");
  toml::table truth = toml::parse_file(truth_file);   // rewritten below, the bench's keys kept
  std::map<std::string, toml::table*> case_tables;
  if (toml::array* cases = truth["case"].as_array())
    for (toml::node& node : *cases)
      if (toml::table* t = node.as_table(); t != nullptr && t->get("name") != nullptr)
        case_tables[t->get("name")->value_or(std::string())] = t;

  std::vector<ident::Term> terms;
  Eigen::VectorXd theta(static_cast<Eigen::Index>(model.terms.size()));
  for (const model::ModelTerm& t : model.terms) {
    theta(static_cast<Eigen::Index>(terms.size())) = t.coefficient;
    terms.push_back(t.term);
  }
  const Eigen::Index first = ident::first_usable_row(terms);
  // The output's white noise per sample: the model's N (its noise analysis on the plan's static
  // stretches) over the root of the sample period, else white_sd. white_sd is the batch
  // innovation's sd, which also carries whatever the model leaves between phases and cases (on a
  // tumble the poses' placement, twice the noise at rest), so it serves only where N is missing.
  const std::optional<double> n_term = model.noise.values[static_cast<std::size_t>(noise::NoiseTerm::N)];
  const auto white_sd_of = [&](const dataset::CaseData& c) {
    return n_term && c.sample_period_s > 0.0 ? *n_term / std::sqrt(c.sample_period_s) : model.white_sd.value_or(0.0);
  };
  double white_sd = 0.0;
  std::mt19937_64 rng(static_cast<std::uint64_t>(truth["seed"].value_or(std::int64_t{1})) ^ 0x6d6f64656c66696cULL);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (dataset::CaseData& c : data.cases) {
    const auto it = case_tables.find(c.name);
    if (it == case_tables.end() || read->m_es.count(c.name) == 0) throw InputError(truth_file + ": no m_es_true for case " + c.name);
    // The bench's fixture misalignment of the case stays: M_E^C = (M_C^S true)^T M_E^S true.
    const frames::Dcm m_es = model.m_cs * read->m_cs.transpose() * read->m_es.at(c.name);
    const ident::SignalSet signals = ident::signals_from_case(c, m_es, data.t_ref, dir.string());
    if (first >= c.y.size()) throw InputError(fmt::format("case {}: {} rows, fewer than the model's lags need", c.name, c.y.size()));
    // The first rows seed the output lags: they keep the bench's own output.
    const Eigen::VectorXd y = procedure::simulate_model(terms, theta, signals, first, model.square_highpass_rad_s, c.sample_period_s);
    white_sd = white_sd_of(c);
    for (Eigen::Index k = 0; k < y.size(); ++k) c.y(first + k) = y(k) + white_sd * noise(rng);
    it->second->insert_or_assign("m_es_true", dcm_array(m_es));
  }
  dataset::write_dataset(dir, data);

  toml::table terms_table;
  for (const model::ModelTerm& t : model.terms) terms_table.insert_or_assign(t.term.to_string(), t.coefficient);
  truth.insert_or_assign("terms", std::move(terms_table));
  truth.insert_or_assign("m_cs", dcm_array(model.m_cs));
  truth.insert_or_assign("model", model_file.string());
  // The bench's parameters describe a sensor this output no longer comes from.
  truth.erase("params");
  if (toml::table* n = truth["noise"].as_table()) n->insert_or_assign("white_sd", white_sd);
  std::ofstream(truth_file) << "# truth of `simulate --model`: the output below comes from the model file named here\n" << truth << "\n";
  fmt::print(summary, "{}: output from model {} ({} terms, white sd {:.4g} from {}; first {} row(s) per case from the bench)\n",
             dir.string(), model_file.string(), terms.size(), white_sd,
             n_term ? "its [noise] N; its other noise terms are not simulated" : "its white_sd (it has no [noise] N)", first);
}

}  // namespace

int run_simulate(const SimulateOptions& options, std::ostream& summary) {
  config::BenchConfig bench = config::load_bench_config(options.bench);
  if (options.seed) config::reseed(bench, *options.seed);
  std::map<std::string, std::filesystem::path> by_sensor;
  for (const auto& [sensor, file] : options.models) {
    if (sensor.empty() && bench.sensors.size() != 1)
      throw InputError("simulate: the bench has several sensors; give --model SENSOR=FILE");
    const std::string name = sensor.empty() ? bench.sensors.front().name : sensor;
    if (std::none_of(bench.sensors.begin(), bench.sensors.end(), [&](const config::SensorUnderTest& s) { return s.name == name; }))
      throw InputError("simulate: --model names sensor '" + name + "', which the bench lacks");
    (void)model::read_model(file);   // bad input before the simulation runs
    by_sensor[name] = file;
  }
  const int rc = sim::run_simulate(options.bench, options.out, summary, options.seed);
  for (const auto& [name, file] : by_sensor) apply_model(bench.sensors.size() == 1 ? options.out : options.out / name, file, summary);
  return rc;
}

}  // namespace inertia::commands
