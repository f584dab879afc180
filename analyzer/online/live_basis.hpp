#pragma once
// The columns the live estimator keeps sufficient statistics of, and how every sensor-frame term
// it may need (the model, the model's external-frame form for algorithm 1, the structure table's
// candidates) is formed from them for any mounting misalignment M_C^S and squares' corner.
//
//  - Base columns: monomials in the mounting's nominal case-frame coordinates (a_x a_y a_z,
//    w_x w_y w_z there; with T, lagged y and unlagged-y factors carried along), so that a term
//    of the sensor frame is a fixed combination of them whose coefficients follow from M
//    (ident/frame_expansion.hpp). A term with abs() or sign() of a sensor axis is not such a
//    combination: it is a base column of its own ("frozen"), evaluated with the mounting's M as
//    estimated when its samples arrived.
//  - Filtered columns: the base monomials of the model's squares a_i^2, a_p^2, a_o^2 passed
//    through eq. 12's high pass s/(s + b), one set per node of the corner grid (corner_grid.hpp:
//    the model's corner, or the grid a continuous corner is interpolated on).
#include <Eigen/Dense>

#include <limits>
#include <optional>
#include <vector>

#include "analyzer/ident/frame_expansion.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/term.hpp"

namespace inertia::online {

/// What the live estimate publishes for a value the data does not determine yet.
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The unlagged term v^power (a_i, a_p^2, T): the monomials the live terms are built from.
inline ident::Term plain_term(ident::Variable v, int power = 1) {
  return ident::Term::from_factors({ident::Factor{v, 0, ident::FactorFunction::Plain, power}});
}

class LiveBasis {
 public:
  /// `terms`: every sensor-frame (or case-frame: a_x, w_x, ...) term that will be asked for;
  /// `filtered`: those whose column passes the squares' high pass (the model's squares; empty:
  /// static squares only).
  LiveBasis(const std::vector<ident::Term>& terms, const std::vector<ident::Term>& filtered);

  [[nodiscard]] const std::vector<ident::Term>& terms() const { return terms_; }
  /// Position of `term` in terms(), or -1.
  [[nodiscard]] Eigen::Index find(const ident::Term& term) const;

  [[nodiscard]] const std::vector<ident::Term>& base() const { return base_; }
  [[nodiscard]] Eigen::Index base_size() const { return static_cast<Eigen::Index>(base_.size()); }
  /// Base positions of the monomials the high pass applies to.
  [[nodiscard]] const std::vector<Eigen::Index>& filtered_sources() const { return filtered_sources_; }
  [[nodiscard]] Eigen::Index filtered_size() const { return static_cast<Eigen::Index>(filtered_sources_.size()); }
  [[nodiscard]] bool has_frozen() const { return has_frozen_; }
  [[nodiscard]] int max_lag() const { return max_lag_; }
  /// Whether some term reads v (T needs temperature, rates need w).
  [[nodiscard]] bool reads(ident::Variable v) const;

  /// Term `term`'s column = base * base_row' + (high-passed filtered sources) * filtered_row'.
  /// With `filtered` false the squares stay static (their monomials in the base). `m`: rows n_i,
  /// n_p, n_o in case coordinates (M_C^S).
  void coefficients(Eigen::Index term, const Eigen::Matrix3d& m, bool filtered,
                    Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> base_row,
                    Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> filtered_row) const;
  /// The same for several terms at once: rows of t_base (terms x base) and t_filtered.
  void transform(const std::vector<Eigen::Index>& terms, const Eigen::Matrix3d& m, bool filtered, Eigen::MatrixXd& t_base,
                 Eigen::MatrixXd& t_filtered) const;
  /// True when the term is a square that passes the high pass (its column depends on the corner).
  [[nodiscard]] bool is_filtered(Eigen::Index term) const { return maps_[static_cast<std::size_t>(term)].square; }

  /// The base columns over rows first_row.. of `signals` (case-frame a_x.., w_x..; sensor-frame
  /// a_i.. with the mounting's M for frozen columns; T; y). `out` is (size - first_row) x base.
  void evaluate(const ident::SignalSet& signals, Eigen::Index first_row, Eigen::Ref<Eigen::MatrixXd> out) const;

 private:
  struct TermMap {
    std::optional<ident::FrameExpansion> expansion;   // none: frozen
    std::vector<Eigen::Index> base;                   // base position of each monomial (or the frozen column)
    std::vector<Eigen::Index> filtered;               // filtered position of each monomial (squares)
    bool square = false;
  };
  Eigen::Index base_index(const ident::Term& monomial);

  std::vector<ident::Term> terms_;
  std::vector<TermMap> maps_;
  std::vector<ident::Term> base_;
  std::vector<Eigen::Index> filtered_sources_;
  bool has_frozen_ = false;
  int max_lag_ = 0;
};

}  // namespace inertia::online
