#pragma once
// A sensor-frame term as a fixed combination of monomials in another frame's coordinates.
//
// Every sensor-frame variable is a linear form in the coordinates of a frame it is turned from:
// with M (rows n_i, n_p, n_o written in that frame, e.g. M_C^S against the case frame),
//     a_i = n_i . a,   a_p = n_p . a,   a_o = n_o . a    (and w_i, w_p, w_o likewise),
// so a term whose sensor-frame factors are plain powers is a polynomial in the other frame's
// coordinates, and its column is a linear combination of that polynomial's monomial columns:
//     a_i*a_p = sum_{c,d} n_i,c n_p,d a_c a_d.
// The monomials do not depend on M, only their coefficients do. Least squares on such terms can
// therefore keep its sufficient statistics (Gram matrix, cross products) in the monomial basis and
// re-derive the statistics of the sensor-frame model for any M afterwards, exactly:
//     Phi_S = Phi_B T(M)^T   =>   Phi_S' Phi_S = T(M) (Phi_B' Phi_B) T(M)^T.
// That is what lets the live estimator run algorithm 1 per mounting at every publish without
// keeping the samples (analyzer/online).
//
// The monomials are written with the external-frame variables a_x a_y a_z (w_x w_y w_z), which
// here mean the coordinates of the frame M is given against (the pipeline does the same when it
// turns a mounting's references into its nominal case frame). Frame-free factors (T, y, e, and
// external-frame factors already in the term) are carried unchanged. abs() and sign() of a
// sensor-frame variable are not polynomials: such terms do not expand (expandable() is false).
#include <Eigen/Dense>

#include <vector>

#include "analyzer/ident/term.hpp"

namespace inertia::ident {

struct FrameMonomial {
  Term monomial;
  double coefficient = 0.0;
};

/// The expansion of one term worked out once, so that its coefficients for any frame cost a few
/// multiplications (the live estimator re-derives them at every step of algorithm 1).
class FrameExpansion {
 public:
  /// Throws std::invalid_argument when the term is not expandable().
  explicit FrameExpansion(const Term& term);
  /// The monomials, in canonical order (the same list expand_in_frame gives).
  [[nodiscard]] const std::vector<Term>& monomials() const { return monomials_; }
  /// Coefficient of each monomial for the frame with rows `m`.
  void coefficients(const Eigen::Matrix3d& m, Eigen::Ref<Eigen::VectorXd> out) const;

 private:
  struct Product {
    std::size_t monomial;
    std::vector<int> entries;   // indices row * 3 + column into M, multiplied together
  };
  std::vector<Term> monomials_;
  std::vector<Product> products_;
};

/// True when every sensor-frame factor (a_i a_p a_o w_i w_p w_o) of `term` is a plain power.
[[nodiscard]] bool expandable(const Term& term);

/// The monomials `term` expands into, in canonical order, each with its coefficient for the frame
/// whose rows are `m` (n_i, n_p, n_o). Every monomial that can carry weight for some M is listed,
/// also where this M gives it a zero coefficient, so the list is the same for every M.
/// Throws std::invalid_argument when the term is not expandable().
[[nodiscard]] std::vector<FrameMonomial> expand_in_frame(const Term& term, const Eigen::Matrix3d& m);

}  // namespace inertia::ident
