// The model the online estimator fits (live_model.hpp).
#include "analyzer/online/live_model.hpp"

#include <algorithm>
#include <numbers>
#include <string>

#include "analyzer/diagnose/candidate_library.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/input_error.hpp"

namespace inertia::online {

using Eigen::Index;
using ident::Term;
using ident::Variable;

namespace {

Term product(Variable a, Variable b) { return Term::from_factors({ident::Factor{a}, ident::Factor{b}}); }

}  // namespace

std::vector<Term> LiveModel::default_terms(dataset::SensorKind sensor, bool temperature) {
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  std::vector<Term> terms;
  if (gyro) {
    // Eq. 5's static part: bias, scale factor, its rate nonlinearity (c_f1: the output times the
    // rate, fitted with ULS's correction) and the g-sensitivity.
    terms = {Term(),
             plain_term(Variable::Wi),
             product(Variable::Y, Variable::Wi),
             plain_term(Variable::Ai),
             plain_term(Variable::Ap),
             plain_term(Variable::Ao)};
  } else {
    // The paper's complete static model (eq. 4, r = 0, table 3's case 3).
    terms = {Term(),
             plain_term(Variable::Ai),
             plain_term(Variable::Ai, 2),
             plain_term(Variable::Ap, 2),
             plain_term(Variable::Ao, 2),
             product(Variable::Ai, Variable::Ap),
             product(Variable::Ai, Variable::Ao),
             product(Variable::Ap, Variable::Ao)};
  }
  if (temperature) {
    // A thermal plan is run for the temperature coefficients of the bias and the scale factor
    // (IEEE Std 1293's K_0T and K_1T; a gyroscope's as eq. 5 has them, c_T1 T and the output
    // times epsilon_T T): without them the temperature's effect lands in the others.
    terms.push_back(plain_term(Variable::T));
    terms.push_back(product(gyro ? Variable::Y : Variable::Ai, Variable::T));
  }
  return terms;
}

LiveModel::LiveModel(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model_file, double t_ref,
                     const OnlineOptions& options)
    : sensor(sensor), t_ref(t_ref), options(options) {
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  if (model_file) {
    if (model_file->sensor != sensor) {
      throw InputError("online: the model is for a " + std::string(dataset::to_string(model_file->sensor)) +
                       ", the bench's sensor is a " + dataset::to_string(sensor));
    }
    model_m_cs = model_file->m_cs;
    for (const model::ModelTerm& t : model_file->terms) model_terms.push_back(t.term);
    if (model_file->square_highpass_rad_s) grid = CornerGrid::single(*model_file->square_highpass_rad_s);
  } else {
    model_terms = default_terms(sensor, options.temperature_candidates);
    searched = true;
  }
  for (const Term& t : model_terms) {
    if (t.is_noise_term()) {
      throw InputError("online: term '" + t.to_string() +
                       "' is a noise lag; the live estimator keeps no residual history across gaps");
    }
    rational = rational || t.is_output_multiplied();
    model_max_lag = std::max<Index>(model_max_lag, t.max_lag());
  }
  const Variable axis = gyro ? Variable::Wi : Variable::Ai;
  if (std::find(model_terms.begin(), model_terms.end(), plain_term(axis)) == model_terms.end()) {
    throw InputError(std::string("online: the model has no scale-factor term '") + ident::variable_name(axis) +
                     "': algorithm 1 needs it to find the misalignment");
  }
  // The squares' corner: the model's, or searched over the batch pipeline's range (1 rad/s to
  // 1e4 rad/s or 0.9 of Nyquist), static squares competing, as the batch does it.
  std::vector<Term> squares;
  for (const Term& t : model_terms)
    if (procedure::is_square_term(t)) squares.push_back(t);
  const bool search_corner = !squares.empty() && !model_file;
  if (search_corner) {
    const double period = options.nominal_sample_period_s;
    const double hi = std::min(1.0e4, period > 0.0 ? 0.9 * std::numbers::pi / period : 1.0e4);
    grid = CornerGrid::spanning(1.0, hi);
  }
  if (grid.empty()) squares.clear();
  // Every term the estimator may be asked for: the model, its external-frame sensitivities, the
  // structure table's candidates, and the factors of output-multiplied terms.
  std::vector<Term> all = model_terms;
  const std::vector<Term> sensitivities = gyro ? std::vector<Term>{plain_term(Variable::Wx), plain_term(Variable::Wy), plain_term(Variable::Wz)}
                                               : std::vector<Term>{plain_term(Variable::Ax), plain_term(Variable::Ay), plain_term(Variable::Az)};
  const auto add = [&all](const Term& t) {
    if (std::find(all.begin(), all.end(), t) == all.end()) all.push_back(t);
  };
  for (const Term& t : sensitivities) add(t);
  std::vector<Term> candidate_terms;
  if (options.structure_table) {
    diagnose::LibraryOptions lo;
    lo.temperature = options.temperature_candidates;
    lo.mounting_rotations = false;
    for (const Term& t : diagnose::candidate_library(sensor, lo)) {
      if (t.is_noise_term() || std::find(model_terms.begin(), model_terms.end(), t) != model_terms.end()) continue;
      // Cross-axis terms are the misalignment's (algorithm 1 per mounting).
      if (t == plain_term(gyro ? Variable::Wp : Variable::Ap) || t == plain_term(gyro ? Variable::Wo : Variable::Ao)) continue;
      candidate_terms.push_back(t);
      add(t);
    }
  }
  for (const Term& t : std::vector<Term>(all))
    if (t.is_output_multiplied()) add(t.denominator_factor());
  basis = std::make_unique<LiveBasis>(all, squares);
  for (const Term& t : model_terms) model.push_back(basis->find(t));
  for (const Term& t : candidate_terms) candidates.push_back(basis->find(t));
  std::vector<Index> sens;
  for (const Term& t : sensitivities) sens.push_back(basis->find(t));
  solver = std::make_unique<LiveSolver>(*basis, model, sens, sensor, grid, search_corner, options.solver);
  for (Index t : model)
    if (procedure::frame_free(basis->terms()[static_cast<std::size_t>(t)])) frame_free_model.push_back(t);
}

}  // namespace inertia::online
