#include "analyzer/procedure/mounting_regressions.hpp"

#include <algorithm>
#include <memory>
#include <stdexcept>

#include "analyzer/ident/row_products.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/whitened_problem.hpp"
#include "common/parallel.hpp"

namespace inertia::procedure {

using ident::Term;

StackedRegression mounting_regression(std::span<const Term> terms, const MountingCases& m, const frames::Dcm& m_cs,
                                      const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                                      std::optional<double> square_corner) {
  StackedRegression s = stack_regressions(terms, stack_inputs(m, m_cs), data.t_ref, label, first_row);
  apply_square_model(s, data, square_corner);
  return s;
}

StackedRegression whitened_regression(std::span<const Term> terms, const MountingCases& m, const frames::Dcm& m_cs,
                                      const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                                      std::optional<double> square_corner, const ArWhitener& whitener) {
  StackedRegression s = mounting_regression(terms, m, m_cs, data, label, first_row, square_corner);
  whitener.apply(s);
  return s;
}

MountingRegressions::MountingRegressions(const MountingCases& m, const dataset::Dataset& data, std::string_view label,
                                         Eigen::Index first_row, std::optional<double> square_corner,
                                         const ArWhitener& whitener, std::span<const Term> cover)
    : m_(m), data_(data), label_(label), first_row_(first_row), square_corner_(square_corner), whitener_(whitener) {
  const std::lock_guard lock(mutex_);
  whiten_missing(cover);
}

bool MountingRegressions::combines(const Term& term) const {
  return ident::expandable(term) && !term.is_output_multiplied() && term.max_lag() <= first_row_;
}

void MountingRegressions::whiten_missing(std::span<const Term> terms) const {
  // Each new term's expansion once, and the monomials it needs that are not whitened yet.
  std::vector<Term> new_terms;
  std::vector<Key> missing;
  for (const Term& term : terms) {
    if (!combines(term) || expanded_.contains(term) || std::find(new_terms.begin(), new_terms.end(), term) != new_terms.end())
      continue;
    new_terms.push_back(term);
    // A square's monomials pass the squares' high pass with it.
    const bool through_highpass = square_corner_.has_value() && is_square_term(term);
    Expanded& e = expanded_.emplace(term, Expanded{ident::FrameExpansion(term), {}, {}}).first->second;
    for (const Term& monomial : e.expansion.monomials()) {
      Key key{monomial, through_highpass};
      if (!column_of_.contains(key) && std::find(missing.begin(), missing.end(), key) == missing.end()) missing.push_back(key);
      e.keys.push_back(std::move(key));
    }
  }
  if (!missing.empty() || !frame_) {
    // The monomials hold no sensor-frame variable: the stack's M_C^S does not enter them.
    std::vector<Term> monomials;
    std::vector<Eigen::Index> highpassed;
    for (const auto& [monomial, through_highpass] : missing) {
      if (through_highpass) highpassed.push_back(static_cast<Eigen::Index>(monomials.size()));
      monomials.push_back(monomial);
    }
    StackedRegression s = stack_regressions(monomials, stack_inputs(m_, frames::Dcm::Identity()), data_.t_ref, label_, first_row_);
    if (!highpassed.empty()) highpass_columns(s.phi, highpassed, s.cases, data_, *square_corner_);
    whitener_.apply(s);
    // The new columns' rows and columns of [M y]'[M y]: against each other and y in one product,
    // against the columns held before one column at a time.
    const auto held = static_cast<Eigen::Index>(gram_index_.size());
    const Eigen::Index added = s.phi.cols();
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(held + added + 1, held + added + 1);
    if (held > 0) {
      gram.topLeftCorner(held, held) = monomial_gram_.topLeftCorner(held, held);
      gram.row(held + added).head(held) = monomial_gram_.row(held).head(held);
      gram(held + added, held + added) = monomial_gram_(held, held);
      for (const auto& [column, k] : gram_index_)
        gram.row(k).segment(held, added).noalias() = Eigen::Map<const Eigen::VectorXd>(column, s.phi.rows()).transpose() * s.phi;
    } else {
      gram(added, added) = s.y.squaredNorm();
    }
    gram.block(held, held, added, added) = ident::gram(s.phi);
    gram.row(held + added).segment(held, added) = ident::cross_product(frame_ ? frame_->y : s.y, s.phi);
    gram.topRightCorner(held + added, 1) = gram.bottomLeftCorner(1, held + added).transpose();
    gram.block(held, 0, added, held) = gram.block(0, held, held, added).transpose();
    monomial_gram_ = std::move(gram);
    const Eigen::MatrixXd& block = blocks_.emplace_back(std::move(s.phi));
    for (std::size_t j = 0; j < missing.size(); ++j) {
      const double* column = block.col(static_cast<Eigen::Index>(j)).data();
      column_of_.emplace(missing[j], column);
      gram_index_.emplace(column, held + static_cast<Eigen::Index>(j));
    }
    if (!frame_) {
      s.phi.resize(s.y.size(), 0);
      s.labels.clear();
      frame_ = std::move(s);
    }
  }
  for (const Term& term : new_terms) {
    Expanded& e = expanded_.at(term);
    for (const Key& key : e.keys) e.columns.push_back(column_of_.at(key));
  }
}

MountingRegressions::DirectPart MountingRegressions::direct_part(std::span<const Term> terms, const frames::Dcm& m_cs) const {
  DirectPart out;
  std::vector<Term> direct_terms;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    if (combines(terms[j])) continue;
    direct_terms.push_back(terms[j]);
    out.at.push_back(static_cast<Eigen::Index>(j));
  }
  if (!direct_terms.empty()) out.rows = whitened_regression(direct_terms, m_, m_cs, data_, label_, first_row_, square_corner_, whitener_);
  return out;
}

StackedRegression MountingRegressions::whitened(std::span<const Term> terms, const frames::Dcm& m_cs) const {
  if (ident::first_usable_row(terms) > first_row_) {
    // Lags beyond the mounting's first row move the rows: built directly.
    return whitened_regression(terms, m_, m_cs, data_, label_, first_row_, square_corner_, whitener_);
  }
  const DirectPart part = direct_part(terms, m_cs);
  const std::vector<Eigen::Index>& direct_at = part.at;
  const StackedRegression& direct = part.rows;

  StackedRegression out;
  std::vector<const Expanded*> combined(terms.size(), nullptr);
  {
    const std::lock_guard lock(mutex_);
    whiten_missing(terms);
    for (std::size_t j = 0; j < terms.size(); ++j)
      if (combines(terms[j])) combined[j] = &expanded_.at(terms[j]);
    out.y = frame_->y;
    out.cases = frame_->cases;
  }
  const Eigen::Index rows = out.y.size();
  if (!direct_at.empty() && direct.phi.rows() != rows) {
    throw std::logic_error("MountingRegressions: the directly built columns have other rows than the monomials'");
  }
  out.labels = ident::to_strings(std::vector<Term>(terms.begin(), terms.end()));
  const auto columns = static_cast<Eigen::Index>(terms.size());
  out.phi.resize(rows, columns);
  // Each column on its own: the same arithmetic on any number of threads.
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(parallel::threads_for(columns))
#endif
  for (Eigen::Index j = 0; j < columns; ++j) {
    const Expanded* e = combined[static_cast<std::size_t>(j)];
    if (e == nullptr) continue;
    Eigen::VectorXd coefficients(static_cast<Eigen::Index>(e->columns.size()));
    e->expansion.coefficients(m_cs, coefficients);
    auto column = out.phi.col(j);
    column.setZero();
    for (std::size_t k = 0; k < e->columns.size(); ++k) {
      const double c = coefficients(static_cast<Eigen::Index>(k));
      if (c != 0.0) column += c * Eigen::Map<const Eigen::VectorXd>(e->columns[k], rows);
    }
  }
  for (std::size_t k = 0; k < direct_at.size(); ++k) out.phi.col(direct_at[k]) = direct.phi.col(static_cast<Eigen::Index>(k));
  if (!direct.rational.columns.empty()) {
    out.rational.factors = direct.rational.factors;
    for (const Eigen::Index c : direct.rational.columns) out.rational.columns.push_back(direct_at[static_cast<std::size_t>(c)]);
  }
  return out;
}

std::optional<RegressionSums> MountingRegressions::sums(std::span<const Term> terms, const frames::Dcm& m_cs) const {
  if (ident::first_usable_row(terms) > first_row_) return std::nullopt;
  if (std::any_of(terms.begin(), terms.end(), [](const Term& t) { return t.is_output_multiplied(); })) return std::nullopt;
  // The terms that do not combine, built as whitened() builds them; the residual holds them.
  DirectPart part = direct_part(terms, m_cs);
  const std::vector<Eigen::Index> direct_at = std::move(part.at);
  auto direct = std::make_shared<const Eigen::MatrixXd>(std::move(part.rows.phi));
  const auto p = static_cast<Eigen::Index>(terms.size());
  // Each combined term as T's row: its monomials' columns and coefficients.
  struct Combination {
    std::vector<Eigen::Index> monomials;   // rows of the monomials' Gram
    Eigen::VectorXd coefficients;
  };
  std::vector<Combination> combinations(terms.size());
  Eigen::MatrixXd monomial_gram;
  std::vector<const double*> monomial_columns;   // in the Gram's order
  const Eigen::VectorXd* y = nullptr;
  {
    const std::lock_guard lock(mutex_);
    whiten_missing(terms);
    for (std::size_t j = 0; j < terms.size(); ++j) {
      if (!combines(terms[j])) continue;
      const Expanded& e = expanded_.at(terms[j]);
      for (const double* column : e.columns) combinations[j].monomials.push_back(gram_index_.at(column));
      combinations[j].coefficients.resize(static_cast<Eigen::Index>(e.columns.size()));
      e.expansion.coefficients(m_cs, combinations[j].coefficients);
    }
    monomial_gram = monomial_gram_;
    monomial_columns.resize(gram_index_.size());
    for (const auto& [column, k] : gram_index_) monomial_columns[std::size_t(k)] = column;
    y = &frame_->y;   // frame_ is set once and never changes
  }
  const Eigen::Index rows = y->size(), k_count = monomial_gram.rows() - 1;
  if (direct->cols() > 0 && direct->rows() != rows)
    throw std::logic_error("MountingRegressions: the directly built columns have other rows than the monomials'");
  // T (monomials x terms): zero for the direct terms.
  Eigen::MatrixXd t = Eigen::MatrixXd::Zero(k_count, p);
  for (Eigen::Index j = 0; j < p; ++j) {
    const Combination& c = combinations[std::size_t(j)];
    for (std::size_t k = 0; k < c.monomials.size(); ++k) t(c.monomials[k], j) += c.coefficients(Eigen::Index(k));
  }
  Eigen::MatrixXd augmented = Eigen::MatrixXd::Zero(p + 1, p + 1);
  augmented.topLeftCorner(p, p) = t.transpose() * monomial_gram.topLeftCorner(k_count, k_count) * t;
  augmented.col(p).head(p) = t.transpose() * monomial_gram.col(k_count).head(k_count);
  augmented(p, p) = monomial_gram(k_count, k_count);
  if (direct->cols() > 0) {
    // The direct columns against the monomials, each other and y.
    Eigen::MatrixXd monomials_direct(k_count, direct->cols());
    for (Eigen::Index k = 0; k < k_count; ++k)
      monomials_direct.row(k).noalias() = Eigen::Map<const Eigen::VectorXd>(monomial_columns[std::size_t(k)], rows).transpose() * *direct;
    const Eigen::MatrixXd terms_direct = t.transpose() * monomials_direct;   // p x d, rows of direct terms 0
    const Eigen::MatrixXd direct_gram = ident::gram(*direct);
    const Eigen::VectorXd direct_y = ident::cross_product(*direct, *y);
    for (std::size_t a = 0; a < direct_at.size(); ++a) {
      const Eigen::Index j = direct_at[a];
      augmented.col(j).head(p) = terms_direct.col(Eigen::Index(a));
      for (std::size_t b = 0; b < direct_at.size(); ++b) augmented(direct_at[b], j) = direct_gram(Eigen::Index(b), Eigen::Index(a));
      augmented(j, p) = direct_y(Eigen::Index(a));
    }
    for (const Eigen::Index j : direct_at) augmented.row(j).head(p) = augmented.col(j).head(p).transpose();
  }
  augmented.row(p).head(p) = augmented.col(p).head(p).transpose();
  augmented.topLeftCorner(p, p) = (0.5 * (augmented.topLeftCorner(p, p) + augmented.topLeftCorner(p, p).transpose())).eval();
  RegressionSums out{ident::NormalEquations(std::move(augmented), rows, ident::to_strings(std::vector<Term>(terms.begin(), terms.end()))), {}};
  out.residuals = [combinations = std::move(combinations), monomial_columns = std::move(monomial_columns), direct, direct_at,
                   y](std::span<const Eigen::Index> columns, const Eigen::VectorXd& theta) {
    // y - Phi theta as y - M (T theta) - D theta_D: each monomial's weight, then one pass in the
    // monomials' order (the same additions on every run).
    Eigen::VectorXd weight = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(monomial_columns.size()));
    Eigen::VectorXd out = *y;
    for (std::size_t a = 0; a < columns.size(); ++a) {
      const auto j = static_cast<std::size_t>(columns[a]);
      const double theta_j = theta(static_cast<Eigen::Index>(a));
      const auto at = std::find(direct_at.begin(), direct_at.end(), columns[a]);
      if (at != direct_at.end()) {
        out -= theta_j * direct->col(at - direct_at.begin());
        continue;
      }
      for (std::size_t k = 0; k < combinations[j].monomials.size(); ++k)
        weight(combinations[j].monomials[k]) += theta_j * combinations[j].coefficients(Eigen::Index(k));
    }
    for (Eigen::Index k = 0; k < weight.size(); ++k)
      if (weight(k) != 0.0) out -= weight(k) * Eigen::Map<const Eigen::VectorXd>(monomial_columns[std::size_t(k)], out.size());
    return out;
  };
  return out;
}

std::size_t MountingRegressions::monomial_columns() const {
  const std::lock_guard lock(mutex_);
  return gram_index_.size();
}

}  // namespace inertia::procedure
