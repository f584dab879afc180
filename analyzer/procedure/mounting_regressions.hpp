#pragma once
// One mounting's regression as algorithm 2 fits it, for any M_C^S: its cases stacked with
// M_C^S, the squares through the mounting's high pass, AR-whitened.
//
// Algorithm 2 builds that regression again for every candidate stage (each stage's fit gives its
// own M_C^S) and for each probe of the twist. A sensor-frame term whose sensor-frame factors are
// plain powers is a fixed combination of monomials in the case frame's coordinates
// (ident/frame_expansion.hpp), and the squares' high pass and the whitener are linear filters that
// act case by case, so with T(M) the expansion's coefficients
//     whiten(highpass(Phi_B T(M)')) = whiten(highpass(Phi_B)) T(M)'.
// MountingRegressions whitens each monomial's column once (a square's monomials also through the
// high pass) and combines them for every M_C^S. Terms that do not expand (abs() or sign() of a
// sensor-frame variable) and output-multiplied terms (their factors ride along unfiltered) are
// stacked and whitened per request, as mounting_regression and the whitener do.
#include <Eigen/Dense>

#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "analyzer/ident/frame_expansion.hpp"
#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/mountings.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace inertia::procedure {

/// The mounting's regression of `terms` with M_C^S = `m_cs` before whitening: its cases stacked
/// from `first_row` on, the squares through the high pass at `square_corner` (none: static squares).
StackedRegression mounting_regression(std::span<const ident::Term> terms, const MountingCases& m, const frames::Dcm& m_cs,
                                      const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                                      std::optional<double> square_corner);

/// The same, AR-whitened: the rows algorithm 2 fits, built directly.
StackedRegression whitened_regression(std::span<const ident::Term> terms, const MountingCases& m, const frames::Dcm& m_cs,
                                      const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                                      std::optional<double> square_corner, const ArWhitener& whitener);

/// A regression given by its normal equations and its residual, not its rows: what algorithm 2's
/// stages need of a mounting's regression (ident::StageProblem::equations).
struct RegressionSums {
  ident::NormalEquations equations;
  /// y - Phi(:, columns) theta over the regression's rows.
  std::function<Eigen::VectorXd(std::span<const Eigen::Index>, const Eigen::VectorXd&)> residuals;
};

/// whitened_regression for one mounting, corner and whitener, for any terms and M_C^S, from the
/// monomials' whitened columns. The referenced mounting, dataset and whitener must outlive it.
/// Thread: whitened() may be called from several threads at once (a monomial not yet whitened is
/// whitened under a lock).
class MountingRegressions {
 public:
  /// Whitens the monomials of `cover` (the terms the caller will ask for) up front, on --jobs threads.
  MountingRegressions(const MountingCases& m, const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                      std::optional<double> square_corner, const ArWhitener& whitener, std::span<const ident::Term> cover);

  /// What whitened_regression(terms, m, m_cs, ...) gives, to rounding.
  [[nodiscard]] StackedRegression whitened(std::span<const ident::Term> terms, const frames::Dcm& m_cs) const;

  /// whitened(terms, m_cs)'s normal equations and residual, to rounding, without its rows: the
  /// combined columns' Gram from the monomials' (T G T'), each residual one pass over the
  /// monomials. Terms that do not combine are built as whitened() builds them and held by the
  /// residual. None where whitened() would build every row directly (lags beyond the first row)
  /// or a term is output-multiplied (its fit needs the rows).
  [[nodiscard]] std::optional<RegressionSums> sums(std::span<const ident::Term> terms, const frames::Dcm& m_cs) const;

  /// The number of whitened monomial columns held (for tests).
  [[nodiscard]] std::size_t monomial_columns() const;

 private:
  /// A monomial's column, and whether it passed the squares' high pass.
  using Key = std::pair<ident::Term, bool>;
  struct Expanded {
    ident::FrameExpansion expansion;
    std::vector<Key> keys;                          // each monomial's column key
    std::vector<const double*> columns;            // and its whitened column (column())
  };

  [[nodiscard]] bool combines(const ident::Term& term) const;
  /// The terms of a request that do not combine: their places in it and their rows, built directly.
  struct DirectPart {
    std::vector<Eigen::Index> at;
    StackedRegression rows;   // empty when every term combines
  };
  [[nodiscard]] DirectPart direct_part(std::span<const ident::Term> terms, const frames::Dcm& m_cs) const;
  /// Expands every term of `terms` that combines() and is not held yet, and whitens the
  /// monomials not held yet: afterwards expanded_ holds each such term with its columns.
  /// Caller holds mutex_.
  void whiten_missing(std::span<const ident::Term> terms) const;

  const MountingCases& m_;
  const dataset::Dataset& data_;
  std::string label_;
  Eigen::Index first_row_;
  std::optional<double> square_corner_;
  const ArWhitener& whitener_;

  mutable std::mutex mutex_;
  /// The whitened monomials, each batch whitened together kept as its stack's matrix (no copy of
  /// its columns); a column is known by its first coefficient, stable as the deque grows.
  mutable std::deque<Eigen::MatrixXd> blocks_;
  mutable std::map<Key, const double*> column_of_;
  mutable std::map<ident::Term, Expanded> expanded_;
  mutable std::optional<StackedRegression> frame_;              // y and the rows' layout, whitened, no columns
  /// [M y]'[M y] of the monomials' columns in columns_' order, y last: their Gram and products
  /// with y, kept up to date as columns are added.
  mutable Eigen::MatrixXd monomial_gram_;
  mutable std::map<const double*, Eigen::Index> gram_index_;
};

}  // namespace inertia::procedure
