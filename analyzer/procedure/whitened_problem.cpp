#include "analyzer/procedure/whitened_problem.hpp"

#include <boost/math/distributions/chi_squared.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "analyzer/noise/allan.hpp"
#include "analyzer/procedure/identifiable_fit.hpp"
#include "analyzer/procedure/square_highpass.hpp"

namespace inertia::procedure {

std::vector<Eigen::Index> square_columns(const std::vector<std::string>& labels) {
  std::vector<Eigen::Index> out;
  for (std::size_t j = 0; j < labels.size(); ++j) {
    if (labels[j] == "1" || labels[j].find("^2") == std::string::npos) continue;
    if (is_square_term(ident::parse_term(labels[j]))) out.push_back(static_cast<Eigen::Index>(j));
  }
  return out;
}

bool has_square_term(const ident::UlsResult& fit) {
  return !square_columns(std::vector<std::string>(fit.labels.begin(), fit.labels.begin() + fit.process_terms)).empty();
}

void apply_square_model(StackedRegression& s, const dataset::Dataset& data, std::optional<double> corner_rad_s) {
  if (!corner_rad_s) return;
  const std::vector<Eigen::Index> squares = square_columns(s.labels);
  if (!squares.empty()) highpass_columns(s.phi, squares, s.cases, data, *corner_rad_s);
}

std::function<double(double)> StaticNoiseLaw::below_record(const ArWhitener& whitener) const {
  const double gain = 1.0 - whitener.coefficients().sum();
  noise::NoiseFit held = fit;
  for (const noise::NoiseTerm t : {noise::NoiseTerm::B, noise::NoiseTerm::K, noise::NoiseTerm::R}) {
    noise::NoiseCoefficient& c = held.terms[static_cast<std::size_t>(t)];
    if (!c.determined || t == noise::NoiseTerm::R) c.value = 0.0;
  }
  const double lowest = 1.0 / static_cast<double>(std::max<Eigen::Index>(plan_rows, 1));
  const double rate = 1.0 / tau0_s;
  return [held, gain, lowest, rate, tau0 = tau0_s](double f) {
    return gain * gain * 0.5 * noise::model_psd(held, std::max(f, lowest) * rate, tau0) * rate;
  };
}

std::optional<StaticNoiseLaw> static_noise_law(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& layout,
                                               const dataset::Dataset& data) {
  StaticNoiseLaw out;
  std::vector<std::vector<noise::AllanPoint>> stretches;
  for (const CaseRows& rows : layout) out.plan_rows += rows.rows;
  for (const noise::Stretch& stretch : noise::static_stretches(data)) {
    const double period = data.cases[stretch.case_index].sample_period_s;
    if (out.tau0_s == 0.0) out.tau0_s = period;
    if (std::abs(period - out.tau0_s) > 1e-9 * out.tau0_s) continue;
    for (const CaseRows& rows : layout) {
      if (rows.case_index != stretch.case_index) continue;
      const Eigen::Index from = std::max(stretch.begin, rows.first_sample), to = std::min(stretch.end, rows.first_sample + rows.rows);
      if (to - from < 64) continue;
      noise::AllanAccumulator allan(out.tau0_s);
      allan.push(residuals.segment(rows.begin + from - rows.first_sample, to - from));
      stretches.push_back(allan.points());
    }
  }
  if (stretches.empty()) return std::nullopt;
  noise::NoiseFitOptions options;
  options.terms[static_cast<std::size_t>(noise::NoiseTerm::R)] = false;   // a drift, not a stationary noise
  try {
    out.fit = noise::fit_noise(noise::pool(stretches), options);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  }
  // A law that does not hold on its own stretches is not carried below them. The gyro bench's
  // Gauss-Markov rate noise (correlation 0.1 s) in dwells of about a second reads as flicker and
  // random walk that fail the stretches' chi-square, and that random walk, held at one cycle per
  // plan, would overstate w_i's sd many times (docs/validation.md, 'Evidence behind choices in
  // the code').
  if (out.fit.dof > 0 && boost::math::cdf(boost::math::complement(boost::math::chi_squared(out.fit.dof), out.fit.chi_square)) < 1e-3)
    return std::nullopt;
  return out;
}

WhiteningOptions whitening_options(const PipelineOptions& options, bool search_square_corner,
                                   std::optional<double> square_corner) {
  WhiteningOptions w;
  w.max_order = options.whitening_max_order;
  w.search_square_corner = search_square_corner;
  w.square_corner = square_corner;
  w.corner_min_rad_s = options.square_highpass_min_rad_s;
  w.corner_max_rad_s = options.square_highpass_max_rad_s;
  w.err = options.selection.err;
  w.uls = options.selection.uls;
  return w;
}

namespace {

/// `residuals` with each case that states its placement (dataset::CaseData::placement_sd_rad)
/// taken about its own level, where every case is a static pose. There a case's level is all it
/// says about the terms, and the inference weighs the levels by what the noise and the stated
/// placements leave of them (random effects, post_selection_inference.hpp); read as noise, the
/// levels a placement tilt leaves are a near unit root of the AR model, which all but removes the
/// poses' means from the whitened rows before they are weighed: a tumble fitted with the selected
/// model's terms (--fixed-model, plan-check's runs) read its bias many times less precisely than
/// the selection did, whose larger candidate set happened to absorb the levels. Where cases move,
/// the levels stay: one AR model serves every case, and the slow part it then carries (flicker
/// within the moving cases) is what the moving cases' terms are weighed by (docs/validation.md,
/// 'plan-check').
Eigen::VectorXd about_stated_placements(Eigen::VectorXd residuals, const std::vector<CaseRows>& cases, const dataset::Dataset& data) {
  const bool poses_only = std::all_of(cases.begin(), cases.end(),
                                      [&](const CaseRows& c) { return data.cases[c.case_index].kind == CaseKind::Static; });
  if (!poses_only) return residuals;
  for (const CaseRows& c : cases) {
    if (!(data.cases[c.case_index].placement_sd_rad > 0.0) || c.rows == 0) continue;
    auto e = residuals.segment(c.begin, c.rows);
    e.array() -= e.mean();
  }
  return residuals;
}

}  // namespace

WhitenedProblem whiten_problem(StackedRegression stacked, const dataset::Dataset& data, const WhiteningOptions& options) {
  WhitenedProblem out;
  out.square_corner_rad_s = options.square_corner;
  const auto search_corner = [&](const StackedRegression& s) {
    const SquareCornerSearch search(s, square_columns(s.labels), data);
    return search.best(options.corner_min_rad_s, std::min(options.corner_max_rad_s, max_corner(s.cases, data)));
  };
  // For the corner's search after the whitening: the squares' columns before their high pass
  // (the other columns do not depend on the corner, and the stack is not copied whole).
  const std::vector<Eigen::Index> squares = square_columns(stacked.labels);
  const bool search_after_whitening = options.search_square_corner && !squares.empty();
  Eigen::MatrixXd unfiltered_squares;
  if (search_after_whitening) {
    unfiltered_squares.resize(stacked.phi.rows(), static_cast<Eigen::Index>(squares.size()));
    for (std::size_t i = 0; i < squares.size(); ++i) unfiltered_squares.col(static_cast<Eigen::Index>(i)) = stacked.phi.col(squares[i]);
    out.square_corner_rad_s = search_corner(stacked);
  }
  apply_square_model(stacked, data, out.square_corner_rad_s);
  // The noise model from the residuals of the full candidate set (dependent columns left out),
  // those of a case that states its placement about the case's own level.
  out.identifiable = identifiable_ranking(stacked, data.sensor, options.err);
  ident::UlsOptions uls = options.uls;
  uls.noise_lags = 0;
  std::vector<std::string> dropped;
  ident::UlsResult ols = fit_identifiable(stacked, data.sensor, out.identifiable, uls, dropped);
  out.noise_law = static_noise_law(ols.residuals, stacked.cases, data);
  out.whitener = ArWhitener::fit(about_stated_placements(std::move(ols.residuals), stacked.cases, data), stacked.cases, options.max_order);
  if (search_after_whitening) {
    // Only the squares depend on the corner: the other columns are whitened once, for the
    // corner's search and as the result, and the squares pass the corner's high pass and the
    // whitener on their own.
    for (std::size_t i = 0; i < squares.size(); ++i) stacked.phi.col(squares[i]) = unfiltered_squares.col(static_cast<Eigen::Index>(i));
    const std::vector<CaseRows> layout = stacked.cases;
    Eigen::MatrixXd& through = unfiltered_squares;
    std::vector<Eigen::Index> all(squares.size());
    for (std::size_t i = 0; i < squares.size(); ++i) all[i] = static_cast<Eigen::Index>(i);
    StackedRegression whitened = std::move(stacked);
    out.whitener.apply(whitened);
    out.square_corner_rad_s = search_corner(whitened);
    if (out.square_corner_rad_s) {
      highpass_columns(through, all, layout, data, *out.square_corner_rad_s);
      out.whitener.apply_to_columns(through, layout);
      for (std::size_t i = 0; i < squares.size(); ++i) whitened.phi.col(squares[i]) = through.col(static_cast<Eigen::Index>(i));
    }
    out.regression = std::move(whitened);
    return out;
  }
  out.whitener.apply(stacked);
  out.regression = std::move(stacked);
  return out;
}

}  // namespace inertia::procedure
