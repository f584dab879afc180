#pragma once
// Model terms (docs/design.md, "Model terms"): the names that appear in reports, JSON and model files,
// and the structure the regressor builder evaluates.
//
// Grammar (whitespace between tokens is ignored on input and never printed):
//   term    := "1" | factor ("*" factor)*
//   factor  := base [power] [lag]  |  base [lag] [power]        (both orders read; see canonical form)
//   base    := variable [lag] | ("abs" | "sign") "(" variable [lag] ")"
//   power   := "^" n              n integer in 1..kMaxPower (a "^1" is dropped)
//   lag     := "[k-" j "]"        j integer in 1..kMaxLag (no lag = the current sample k)
// A factor carries at most one lag. Variables, in canonical order:
//   a_i a_p a_o   specific force in the sensor frame F_S, m/s^2
//   a_x a_y a_z   specific force in the external frame F_E, m/s^2
//   w_i w_p w_o   rate in F_S, rad/s;   w_x w_y w_z   rate in F_E, rad/s
//   T             temperature minus the dataset's t_ref, degC
//   y             the sensor output: only lagged, or unlagged inside a product with another
//                 factor (the output-multiplied terms of rational models, paper eq. 5: y*T, y*w_i)
//   e             the one-step prediction residual (noise) v(k) of the paper's eqs. 2 and 4 (an
//                 extension of the paper's variables); only lagged (e[k-1] is c_1 v(k-1), the MA
//                 part). Its values are supplied by the estimator (extended least squares), not
//                 the dataset.
//
// Canonical form (to_string): the unlagged output y first when present (docs/design.md spells the
// output-multiplied terms y*T, y*w_i), then factors sorted by variable (order above), then by lag
// (current sample first), then plain < abs < sign; equal factors merged into powers; a lagged plain
// factor prints its power before the lag (`a_o^2[k-1]` = a_o[k-1]^2); abs and sign print the lag
// inside the parentheses (`abs(a_i[k-1])`). The factors of one variable at one lag are reduced
// with the exact identities x = |x| sign(x), sign(x)^2 = 1 (x != 0), to one of: x^m,
// x^m*abs(x) (m >= 0), or sign(x). So abs(a_i)^2 -> a_i^2, a_i*sign(a_i) -> abs(a_i),
// abs(a_i)^3 -> a_i^2*abs(a_i), and a product that reduces to a constant (sign(a_i)^2) is refused
// rather than silently aliasing the bias. "1" must stand alone.
#include <compare>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/dataset/dataset.hpp"

namespace inertia::ident {

enum class Variable : std::uint8_t { Ai, Ap, Ao, Ax, Ay, Az, Wi, Wp, Wo, Wx, Wy, Wz, T, Y, E };
inline constexpr int kVariableCount = 15;
inline constexpr int kMaxLag = 1000;    // beyond any model order we fit; bounds the row offset
inline constexpr int kMaxPower = 16;    // beyond it the columns overflow or underflow in m/s^2

/// "a_i", "w_x", "T", "y", "e", ...
const char* variable_name(Variable v);

enum class FactorFunction : std::uint8_t { Plain, Abs, Sign };

/// One factor f(v[k - lag])^power.
struct Factor {
  Variable variable = Variable::Ai;
  int lag = 0;                 // 0 = current sample k; j >= 1 means k - j
  FactorFunction function = FactorFunction::Plain;
  int power = 1;               // >= 1

  /// Variable, lag, function, then power (the canonical order apart from the y-first rule).
  friend auto operator<=>(const Factor&, const Factor&) = default;
  friend bool operator==(const Factor&, const Factor&) = default;
};

class Term {
 public:
  /// The bias term "1" (no factors).
  Term() = default;

  /// Canonicalizes and validates `factors` (see the header comment). Throws InputError naming
  /// the term and the rule it breaks (y or e alone or unlagged, a power of sign, ...).
  static Term from_factors(std::vector<Factor> factors);

  [[nodiscard]] const std::vector<Factor>& factors() const { return factors_; }
  [[nodiscard]] bool is_bias() const { return factors_.empty(); }

  /// Canonical text: `1`, `a_i^2`, `a_i*abs(a_i)`, `a_o^2[k-1]`, `y*w_i`.
  [[nodiscard]] std::string to_string() const;

  /// Largest lag of any factor (0 for a static term): the first usable sample is k = max_lag().
  [[nodiscard]] int max_lag() const;

  /// True when the term holds the unlagged output y(k): a denominator term of a rational model
  /// (paper eq. 5), moved to the right-hand side, so it is correlated with the noise and needs an
  /// estimator that corrects for that (the ULS / RME of section 2.6).
  [[nodiscard]] bool is_output_multiplied() const;
  /// For an output-multiplied term y*p: p, the factor the output multiplies (p_b of
  /// uls_batch.hpp), i.e. the term with one power of the unlagged y removed ("y*w_i" -> "w_i").
  /// Any other term is returned unchanged.
  [[nodiscard]] Term denominator_factor() const;

  /// True when the term holds a lagged residual e[k-j]: its column can be built only once the
  /// estimator provides residuals.
  [[nodiscard]] bool is_noise_term() const;

  /// The distinct variables the term reads, in canonical order.
  [[nodiscard]] std::vector<Variable> variables() const;
  [[nodiscard]] bool uses(Variable v) const;

  friend auto operator<=>(const Term&, const Term&) = default;
  friend bool operator==(const Term&, const Term&) = default;

 private:
  std::vector<Factor> factors_;   // canonical: sorted, merged
};

/// Parses a term and returns it in canonical form. Throws InputError whose message holds the
/// offending text and the 1-based character position in it (e.g. "term 'a_q': unknown variable
/// 'a_q' at character 1"): unknown variable, lag 0, malformed lag or power, empty factor, y or e
/// where they are not allowed.
Term parse_term(std::string_view text);

/// Parses every term; a duplicate (after canonicalization) throws InputError naming both spellings.
std::vector<Term> parse_terms(const std::vector<std::string>& texts);

/// The canonical text of each term.
std::vector<std::string> to_strings(const std::vector<Term>& terms);

/// Physical meaning of a term for a sensor of `kind`, as it appears in reports (docs/design.md list):
/// "bias", "scale factor", "misalignment/cross-axis sensitivity", "second-order nonlinearity",
/// "cross-coupling (vibropendulous)", "rectification", "odd quadratic", "asymmetry/hysteresis",
/// "bias temperature coefficient", "scale-factor temperature coefficient", "dynamics",
/// "g-sensitivity", "scale-factor nonlinearity", "coloured noise"; plus, for products the list
/// does not name, "higher-order nonlinearity" (a power >= 3 or a mixed product of more than two
/// inputs) and, for an accelerometer term in a rate, "rate sensitivity".
/// Precedence: bias; any e -> coloured noise; any lag -> dynamics; unlagged y -> scale-factor
/// temperature coefficient (y*T^n) or scale-factor nonlinearity (otherwise); T alone -> bias
/// temperature coefficient; T times an input -> scale-factor temperature coefficient; for a gyro
/// any a_* -> g-sensitivity; then the input patterns (the sensed quantity is a_* for an
/// accelerometer and w_* for a gyro): v_i -> scale factor; another axis -> misalignment/cross-axis;
/// v^2 -> second-order nonlinearity; v*u -> cross-coupling; abs(v) -> rectification; v*abs(v)
/// -> odd quadratic; sign(v) -> asymmetry/hysteresis.
const char* physical_name(const Term& term, dataset::SensorKind kind);

}  // namespace inertia::ident
