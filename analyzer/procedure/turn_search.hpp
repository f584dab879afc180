#pragma once
// The search for the aligned mountings' turns against the reference mounting (relative_twists.hpp),
// written once. The batch (relative_twists, on its whitened rows) and the live estimate
// (online::LiveSolver::relative_turns, on its statistics) implement TurnedBatch, what the search
// asks of a regression; the parameters, which twist is held, the steps and when they stop are this
// file's.
#include <Eigen/Dense>

#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace inertia::procedure {

/// A search for a mounting's turn stops once every step is at most this fraction of its
/// parameter's sd: far below what the data determine, and above the searches' own rounding.
inline constexpr double kTurnConvergence = 1e-6;
/// ... and gives up after this many steps (a twist of a degree or two is nearly linear in the
/// columns: each step gains about three digits, so a search that has not converged by then is
/// wandering on a flat residual).
inline constexpr int kTurnMaxSteps = 12;
/// A search that gave up with a last step above this fraction of a parameter's sd has not found
/// the least residual to within what the data determine: the residual wanders along the twists or
/// has several minima there (a tilt the plan holds away from its truth does this), so the twists
/// it moved are held. Below it, where the search stopped is as good as the least residual.
inline constexpr double kTurnSettled = 0.1;
/// The step (rad) of the central differences that give the prediction's derivative with respect
/// to a turn: the fitted prediction is smooth in the turn (products of the rotation's entries),
/// so the difference's truncation (h^2) is far below the data's resolution.
inline constexpr double kTurnDerivativeStepRad = 1e-4;

/// One parameter of the search: component `axis` of a turn of mounting `mounting` (turned()'s
/// parameters: 0 and 1 the tilts, 2 the twist about n_i).
struct TurnParameter {
  std::size_t mounting = 0;
  int axis = 2;
};

/// Per mounting (`mountings` of them), the turn `x` gives the parameters: zero for a mounting none
/// of them turns. Every turned mounting has its twist among the parameters (search_turns).
std::vector<Eigen::Vector3d> turns_of(std::span<const TurnParameter> parameters, const Eigen::VectorXd& x,
                                      std::size_t mountings);

/// A step of the search and the parameters' information there (the model's terms re-fitted at
/// every value, the other parameters free).
struct TurnStep {
  Eigen::VectorXd delta;
  Eigen::MatrixXd information;
};

/// Why a twist stays at the nominal frame, and the figures that say so.
struct TwistHeld {
  enum class Reason {
    SdAboveTolerance,             // at the nominal frame its sd (tilts free) exceeds the tolerance
    SearchDidNotSettle,           // the steps did not settle (kTurnSettled), or the batch lost its fit
    SdAboveToleranceWhereFound,   // the search settled where the twist's sd exceeds the tolerance
  };
  Reason reason = Reason::SdAboveTolerance;
  double sd_rad = 0.0;          // at the nominal frame, its tilts free
  double found_rad = 0.0;       // the last two reasons: where the search stopped, from the nominal frame
  double found_sd_rad = 0.0;    // ... and its sd there
};

/// What the search asks of the batch regression whose mountings it turns.
class TurnedBatch {
 public:
  virtual ~TurnedBatch() = default;
  /// The step toward the batch's least residual from the mountings' current turns; none when the
  /// batch has no fit there.
  virtual std::optional<TurnStep> step(std::span<const TurnParameter> parameters) = 0;
  /// Turns the parameters' mountings by `delta`. `covariance`: the parameters' (the information's
  /// inverse at the step).
  virtual void turn(std::span<const TurnParameter> parameters, const Eigen::VectorXd& delta,
                    const Eigen::MatrixXd& covariance) = 0;
  /// Returns `mountings` to the frames the search started from, and forgets what turn() recorded
  /// of them.
  virtual void restore(std::span<const std::size_t> mountings) = 0;
  /// The twist `parameters[twist]` is not determined (`why`): it stays at the nominal frame.
  /// `information`: of every parameter at the nominal frames.
  virtual void hold(std::span<const TurnParameter> parameters, std::size_t twist, const Eigen::MatrixXd& information,
                    const TwistHeld& why) = 0;
};

/// For the user: why the twist of mounting `mounting` against `reference` is held (batch and live).
std::string held_twist_note(std::string_view mounting, std::string_view reference, const TwistHeld& why,
                            double tolerance_rad);

/// The mountings `turning` turned against the reference, each by its twist about n_i and the tilts
/// its excitation determines (`tilts_determined[mounting][axis]`, turned()'s axes 0 and 1): the
/// tilts join because a held twist leaks into them. At the nominal frames a twist whose sd with the
/// tilts free exceeds `tolerance_rad` is held (TurnedBatch::hold) and the step is taken again
/// without it; then steps until kTurnConvergence or kTurnMaxSteps. A search that did not settle
/// (kTurnSettled) is undone and its twists held; one that settled where a twist's sd exceeds the
/// tolerance is undone, that twist held, and the search run again without it. Returns the
/// mountings turned.
std::vector<std::size_t> search_turns(TurnedBatch& batch, std::vector<std::size_t> turning,
                                      std::span<const std::array<bool, 2>> tilts_determined, double tolerance_rad);

/// The sd of the parameters: the square roots of the diagonal of the information's inverse.
Eigen::VectorXd turn_sd(const Eigen::MatrixXd& information, Eigen::MatrixXd* covariance = nullptr);

}  // namespace inertia::procedure
