#pragma once
// The regression matrix Phi of a term list over one test case (paper section 2.6: the models of
// eqs. 2, 4, 5 and 6 are linear in the parameters, y = Phi theta + v).
//
//   Phi(r, j) = term_j evaluated at sample k = first_row + r,   r = 0 .. N - 1 - first_row
//   y_out(r)  = y(first_row + r)
//
// first_row is the largest lag of any term (or more when asked), so every lagged factor refers to
// a sample inside the case: rows are never padded with invented values.
#include <Eigen/Dense>
#include <array>
#include <bitset>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "analyzer/ident/term.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::ident {

/// Per-sample values of every variable a term can read, all of one length, SI units (a in
/// m/s^2, w in rad/s, T in degC relative to t_ref). Variables a case lacks are simply absent.
class SignalSet {
 public:
  /// `origin` names where the signals come from in error messages, e.g.
  /// "case 'shaker-ia' of dataset my-test".
  explicit SignalSet(Eigen::Index samples = 0, std::string origin = {});

  [[nodiscard]] Eigen::Index size() const { return samples_; }
  [[nodiscard]] const std::string& origin() const { return origin_; }

  /// Sets (or replaces) a variable. Throws std::invalid_argument when the length differs from size().
  void set(Variable v, Eigen::VectorXd values);
  [[nodiscard]] bool has(Variable v) const { return values_[index(v)].has_value(); }
  /// Throws std::out_of_range when the variable is absent.
  [[nodiscard]] const Eigen::VectorXd& get(Variable v) const;

 private:
  static std::size_t index(Variable v) { return static_cast<std::size_t>(v); }
  Eigen::Index samples_ = 0;
  std::string origin_;
  std::array<std::optional<Eigen::VectorXd>, kVariableCount> values_;
};

/// Which variables a caller needs of a case (the variables of its terms).
using VariableSet = std::bitset<kVariableCount>;

/// The variables `terms` are built from.
VariableSet variables_of(std::span<const Term> terms);

/// How a case's samples are read beyond M_E^S: the frame its external variables (a_x .. w_z) are
/// given in, as the rotation from F_E into it (identity: F_E itself; a mounting's fit reads them in
/// its nominal case frame, M_E^C), and an offset taken from the output (a bias known from
/// another mounting).
struct CaseReading {
  Eigen::Matrix3d external = Eigen::Matrix3d::Identity();
  double y_offset = 0.0;
};

/// Signals of one case: a_i, a_p, a_o = M_E^S a_E per sample; a_x, a_y, a_z = a_E (turned by
/// `reading.external`); w likewise when the case has w_x, w_y, w_z; T = temp - t_ref when it has
/// temp; y (less `reading.y_offset`). Not e: the estimator sets it (SignalSet::set(Variable::E,
/// residuals)) once it has residuals.
/// `dataset_label` names the dataset in error messages (its folder, usually). With `only`, just
/// those variables (a stack of some terms copies no column it does not use).
SignalSet signals_from_case(const dataset::CaseData& c, const Eigen::Matrix3d& m_es, double t_ref,
                            std::string_view dataset_label = {}, const std::optional<VariableSet>& only = std::nullopt,
                            const CaseReading& reading = {});

/// The same for case `case_index` of `data` (t_ref and the label from `data`).
SignalSet signals_from_dataset(const dataset::Dataset& data, std::size_t case_index, const Eigen::Matrix3d& m_es);

/// The name of the dataset column (or other source) a variable comes from: "temp" for T,
/// "w_x, w_y, w_z" for rates, "y", ...
std::string source_of(Variable v);

/// Throws InputError when a term needs a variable `signals` lacks, e.g. "term 'a_i*T' needs
/// column 'temp', which case 'shaker-ia' of dataset my-test lacks".
void check_signals(std::span<const Term> terms, const SignalSet& signals);

/// Largest lag over the terms: the first sample index for which every term is defined.
[[nodiscard]] Eigen::Index first_usable_row(std::span<const Term> terms);

struct Regression {
  Eigen::MatrixXd phi;        // (N - first_row) x terms, column-major, column j = term j
  Eigen::VectorXd y;          // y(first_row .. N - 1)
  Eigen::Index first_row = 0; // sample index of row 0 (the row offset)
};

/// Builds Phi and the aligned output. first_row = max(first_usable_row(terms), min_first_row);
/// pass a larger min_first_row to align models of different orders on the same samples.
/// Throws InputError for a missing variable (check_signals) or a case too short for the lags.
/// Cost: every column is a product of lagged signal segments written straight into Phi (no
/// temporaries); Phi's pages are advised as huge pages, since first-touching hundreds of MB in
/// 4 KiB pages cost more than the arithmetic (timings: tests/bench/regressors_benchmark.cpp;
/// docs/validation.md, 'Evidence behind choices in the code'). Not real-time: allocates Phi.
Regression build_regression(std::span<const Term> terms, const SignalSet& signals, Eigen::Index min_first_row = 0);

/// Fills a caller-sized phi (signals.size() - first_row rows, terms.size() columns); allocates
/// nothing. Same checks as build_regression; throws std::invalid_argument on a wrong shape or a
/// first_row below the largest lag.
void fill_regressors(std::span<const Term> terms, const SignalSet& signals, Eigen::Index first_row,
                     Eigen::Ref<Eigen::MatrixXd> phi);

}  // namespace inertia::ident
