#pragma once
// What a test plan's excitation can determine, for any plan: one rule, used by the
// batch pipeline on data and by the live solver on its sufficient statistics.
//
// A mounting's misalignment is read from the sensitivities theta = k n_i along the case axes
// (algorithm 1): tilting n_i toward XRA changes the output by k a_XRA, toward YRA by k a_YRA, and
// the scale factor multiplies a_IRA. An axis therefore determines its parameter only when its
// input varies on its own: separately from the bias (a constant input, such as gravity on a
// single static pose, is a bias) and from the axes before it (on a one-axis shaker a_IRA and
// a_YRA are the same vibration). What is left of an axis's energy after those is its own
// excitation. A reference that does not move still carries its instruments' noise, and a fit
// would read that noise as excitation (errors in variables: the tilt comes out near zero with a
// small, false sd), so the rule is a share of the plan's energy, not a test on the fit: an axis
// whose own excitation is below kMinExcitationShare of the mounting's input energy (1 % in
// amplitude; the monitors' noise sits near 1e-7 of g^2, a real 1 deg tilt of gravity at 3e-4)
// is not determined, and its angle is held at the nominal case frame.
#include <Eigen/Dense>

#include <array>
#include <string>
#include <vector>

#include "analyzer/ident/term.hpp"

namespace inertia::procedure {

inline constexpr double kMinExcitationShare = 1e-4;

/// Temperature terms need the temperature to move: a span below this (degC) is the controller's
/// regulation and the sensor's noise (0.01-0.1 degC), and a near-constant T column would stand in
/// for the bias.
inline constexpr double kMinTemperatureSpanC = 1.0;

/// The case axes IRA, XRA, YRA of a mounting (accelerometers: specific force; gyroscopes: rate).
struct AxisExcitation {
  /// Energy of each axis's input orthogonal to the bias (when estimated) and to the determined
  /// axes before it, over the energy of all three inputs (means included).
  std::array<double, 3> share{};
  std::array<bool, 3> determined{};
  [[nodiscard]] bool scale_determined() const { return determined[0]; }
  [[nodiscard]] bool all_determined() const { return determined[0] && determined[1] && determined[2]; }
  /// Whether algorithm 1 can align the mounting: its scale axis and at least one tilt determined.
  [[nodiscard]] bool aligns() const { return determined[0] && (determined[1] || determined[2]); }
};

/// From the Gram matrix G (4 x 4) of [a_IRA a_XRA a_YRA 1] over a mounting's rows (1: the constant
/// column; pass with_bias = false when the mounting's bias is known or not estimated).
AxisExcitation axis_excitation(const Eigen::Matrix4d& gram, bool with_bias);

/// For the user: which excitation an undetermined axis needs. `axis` 1 (XRA) or 2 (YRA) names the
/// angle; gyro: rates instead of specific force.
std::string missing_excitation(int axis, bool gyro);

/// One note per angle the excitation leaves held at the nominal case frame (none when algorithm 1
/// determines them all), with what it needs: the report's and the live estimate's wording.
/// `with_bias` as for axis_excitation.
std::vector<std::string> held_angle_notes(const AxisExcitation& excitation, bool gyro, bool with_bias);

/// Whether a term holds in any frame near the sensor's: the bias, and products of the sensitive
/// input's first power with temperature, output, lags or noise. Squares, abs(), sign() and the
/// cross-axis inputs need the sensor frame, which a plan that aligns no mounting does not give.
bool frame_free(const ident::Term& term);

}  // namespace inertia::procedure
