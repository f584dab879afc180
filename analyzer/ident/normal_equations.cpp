// The normal equations and the identifiability rules on them (normal_equations.hpp).
#include "analyzer/ident/normal_equations.hpp"

#include <boost/math/distributions/chi_squared.hpp>

#include <algorithm>
#include <optional>
#include <stdexcept>

#include "analyzer/ident/row_products.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/ident/term.hpp"
#include "common/input_error.hpp"

namespace inertia::ident {

bool is_sensitivity_label(std::string_view label, dataset::SensorKind sensor) {
  if (sensor == dataset::SensorKind::Gyroscope) return label == "w_x" || label == "w_y" || label == "w_z" || label == "w_i";
  return label == "a_x" || label == "a_y" || label == "a_z" || label == "a_i";
}

std::vector<Index> sensitivities_then_bias(const std::vector<std::string>& labels, dataset::SensorKind sensor) {
  std::vector<Index> out;
  for (std::size_t j = 0; j < labels.size(); ++j)
    if (is_sensitivity_label(labels[j], sensor)) out.push_back(static_cast<Index>(j));
  for (std::size_t j = 0; j < labels.size(); ++j)
    if (labels[j] == "1") out.push_back(static_cast<Index>(j));
  return out;
}

NormalEquations::NormalEquations(Eigen::MatrixXd augmented, Index samples, std::vector<std::string> labels,
                                 std::vector<Index> output_multiplied, Eigen::MatrixXd factor_gram,
                                 Eigen::VectorXd factor_sum)
    : augmented_(std::move(augmented)),
      samples_(samples),
      labels_(std::move(labels)),
      output_multiplied_(std::move(output_multiplied)),
      factor_gram_(std::move(factor_gram)),
      factor_sum_(std::move(factor_sum)) {
  const auto p = static_cast<Index>(labels_.size());
  if (augmented_.rows() != p + 1 || augmented_.cols() != p + 1)
    throw std::invalid_argument("NormalEquations: " + std::to_string(p) + " labels for a Gram matrix of " +
                                std::to_string(augmented_.rows()) + " x " + std::to_string(augmented_.cols()));
  const auto q = static_cast<Index>(output_multiplied_.size());
  if (q > 0 && (factor_gram_.rows() != q || factor_gram_.cols() != q || factor_sum_.size() != q))
    throw std::invalid_argument("NormalEquations: factor sums must be q x q and q");
  for (const Index c : output_multiplied_)
    if (c < 0 || c >= p) throw std::invalid_argument("NormalEquations: output-multiplied column out of range");
}

NormalEquations NormalEquations::from_rows(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                                           const Eigen::Ref<const Eigen::VectorXd>& y, std::vector<std::string> labels,
                                           const OutputMultiplied& rational) {
  Eigen::MatrixXd augmented = std::move(ErrGram::from_data(phi, y).matrix());
  Eigen::MatrixXd factor_gram;
  Eigen::VectorXd factor_sum;
  if (!rational.columns.empty()) {
    const Eigen::MatrixXd factors = denominator_factors(phi, y, rational, labels);
    factor_gram = ident::gram(factors);
    factor_sum = factors.colwise().sum().transpose();
  }
  return {std::move(augmented), phi.rows(), std::move(labels), rational.columns, std::move(factor_gram),
          std::move(factor_sum)};
}

void NormalEquations::set_successive_differences(Eigen::MatrixXd augmented, Index pairs) {
  if (augmented.rows() != augmented_.rows() || augmented.cols() != augmented_.cols())
    throw std::invalid_argument("NormalEquations: the differences' Gram matrix is not the equations' size");
  if (pairs < 0) throw std::invalid_argument("NormalEquations: a negative number of differenced rows");
  difference_augmented_ = std::move(augmented);
  difference_pairs_ = pairs;
}

void NormalEquations::set_successive_differences(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                                                 const Eigen::Ref<const Eigen::VectorXd>& y,
                                                 std::span<const Index> stretch_starts) {
  const Index n = phi.rows();
  if (y.size() != n) throw std::invalid_argument("NormalEquations: y and Phi differ in length");
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(phi.cols() + 1, phi.cols() + 1);
  Index pairs = 0;
  for_each_stretch(n, stretch_starts, [&](Index begin, Index end) {
    if (end - begin < 2) return;
    const Index m = end - begin - 1;
    Eigen::MatrixXd d(m, phi.cols() + 1);
    d.leftCols(phi.cols()) = phi.middleRows(begin + 1, m) - phi.middleRows(begin, m);
    d.col(phi.cols()) = y.segment(begin + 1, m) - y.segment(begin, m);
    gram += ErrGram::from_data(d.leftCols(phi.cols()), d.col(phi.cols())).matrix();
    pairs += m;
  });
  set_successive_differences(std::move(gram), pairs);
}

Eigen::MatrixXd NormalEquations::augmented(std::span<const Index> positions) const {
  const auto p = static_cast<Index>(positions.size());
  const Index y = augmented_.rows() - 1;
  Eigen::MatrixXd out(p + 1, p + 1);
  for (Index i = 0; i <= p; ++i)
    for (Index j = 0; j <= p; ++j)
      out(i, j) = augmented_(i < p ? positions[static_cast<std::size_t>(i)] : y, j < p ? positions[static_cast<std::size_t>(j)] : y);
  return out;
}

UlsStatistics NormalEquations::statistics(std::span<const Index> positions) const {
  std::vector<Index> den;       // positions of the subset that are output-multiplied
  std::vector<Index> factor;    // their rows in factor_gram_
  for (std::size_t j = 0; j < positions.size(); ++j) {
    const auto it = std::find(output_multiplied_.begin(), output_multiplied_.end(), positions[j]);
    if (it == output_multiplied_.end()) continue;
    den.push_back(static_cast<Index>(j));
    factor.push_back(static_cast<Index>(it - output_multiplied_.begin()));
  }
  const auto q = static_cast<Index>(den.size());
  Eigen::MatrixXd fg(q, q);
  Eigen::VectorXd fs(q);
  for (Index a = 0; a < q; ++a) {
    fs(a) = factor_sum_(factor[static_cast<std::size_t>(a)]);
    for (Index b = 0; b < q; ++b) fg(a, b) = factor_gram_(factor[static_cast<std::size_t>(a)], factor[static_cast<std::size_t>(b)]);
  }
  return UlsStatistics::from_gram(augmented(positions), samples_, den, fg, fs);
}

namespace {

/// Per label, the column of the same term with every lag less by its smallest (T[k-1] -> T,
/// T[k-2]^2 -> T[k-1]^2), or -1. Only the temperature's terms have such a form: it moves over
/// minutes, so one sample's lag is no information of its own unless the data say so. A motion
/// input's lag is the dynamics the model order r was chosen for, and its lags rank as they come.
std::vector<Index> unlagged_forms(const std::vector<std::string>& labels) {
  std::vector<Index> out(labels.size(), -1);
  std::vector<std::optional<Term>> terms;
  for (const std::string& label : labels) {
    try {
      terms.push_back(parse_term(label));
    } catch (const InputError&) {
      terms.emplace_back();   // a column that is no term (a nuisance parameter's)
    }
  }
  for (std::size_t j = 0; j < terms.size(); ++j) {
    if (!terms[j] || terms[j]->factors().empty()) continue;
    std::vector<Factor> factors = terms[j]->factors();
    if (std::any_of(factors.begin(), factors.end(), [](const Factor& f) { return f.variable != Variable::T; })) continue;
    const int least = std::min_element(factors.begin(), factors.end(), [](const Factor& a, const Factor& b) {
                        return a.lag < b.lag;
                      })->lag;
    if (least == 0) continue;
    for (Factor& f : factors) f.lag -= least;
    const Term unlagged = Term::from_factors(std::move(factors));
    for (std::size_t k = 0; k < terms.size(); ++k)
      if (terms[k] && *terms[k] == unlagged) out[j] = static_cast<Index>(k);
  }
  return out;
}

}  // namespace

IdentifiableRanking rank_identifiable(const NormalEquations& equations, dataset::SensorKind sensor, const ErrOptions& base,
                                      std::span<const Index> nuisance) {
  ErrOptions options = base;
  options.forced = sensitivities_then_bias(equations.labels(), sensor);
  options.forced.insert(options.forced.end(), nuisance.begin(), nuisance.end());
  options.reference = ErrReference::AfterForced;
  options.preferred = unlagged_forms(equations.labels());
  options.tie_energy = 0.0;
  ErrRanking ranking = err_rank(equations.augmented(), options);
  const bool lagged_pairs = std::any_of(options.preferred.begin(), options.preferred.end(), [](Index k) { return k >= 0; });
  const auto dof = static_cast<double>(equations.samples() - static_cast<Index>(ranking.order.size()));
  if (lagged_pairs && dof > 0.0) {
    const double sigma2 = std::max(0.0, ranking.unexplained * ranking.reference_energy) / dof;
    options.tie_energy = boost::math::quantile(boost::math::complement(boost::math::chi_squared(1.0), kLagTieLevel)) * sigma2;
    ranking = err_rank(equations.augmented(), options);
  }
  return {std::move(ranking.order), std::move(ranking.dependent)};
}

}  // namespace inertia::ident
