#pragma once
// A discrete transfer function num(q^-1)/den(q^-1) and its direct-form-II-transposed realisation.
// The paper's equation 5 writes the FOG's coloured noise and g-sensitivity as such ratios of
// polynomials in the backward shift q^-1; the accelerometer's high-pass K(s) terms of equation 12
// become first-order ones after discretisation.
#include <Eigen/Dense>
#include <array>
#include <cstddef>
#include <span>
#include <string_view>

namespace inertia::sim {

/// A discrete transfer function num(q^-1)/den(q^-1), den[0] = 1:
///   y(k) = num[0] u(k) + ... + num[n] u(k-n) - den[1] y(k-1) - ... - den[n] y(k-n).
template <std::size_t Order>
struct DiscreteTransferFunction {
  std::array<double, Order + 1> num{};
  std::array<double, Order + 1> den{};
};

/// Throws std::invalid_argument naming `name` when a coefficient is not finite, den[0] != 1, or
/// den has a root on or outside the unit circle (Schur-Cohn step-down test, exact for roots on
/// the circle such as the integrator 1 - q^-1, which an eigenvalue solver only approximates).
void validate_transfer_function(std::span<const double> num, std::span<const double> den,
                                std::string_view name);

/// Direct form II transposed: the form with the fewest states and, for the low orders here, good
/// round-off behaviour; y(k) = num[0] u(k) + s[0];  s[i] = num[i+1] u - den[i+1] y + s[i+1].
/// Construction validates (not real-time); step() is real-time safe (no allocation, no branch on
/// data). A default-constructed filter outputs zero.
template <std::size_t Order>
class DiscreteFilter {
 public:
  using StateMatrix = Eigen::Matrix<double, static_cast<int>(Order), static_cast<int>(Order)>;
  using StateVector = Eigen::Matrix<double, static_cast<int>(Order), 1>;

  DiscreteFilter() { tf_.den[0] = 1.0; }
  DiscreteFilter(const DiscreteTransferFunction<Order>& tf, std::string_view name) : tf_(tf) {
    validate_transfer_function(tf_.num, tf_.den, name);
  }

  double step(double u) noexcept {
    const double y = tf_.num[0] * u + state_[0];
    for (std::size_t i = 0; i + 1 < Order; ++i)
      state_[i] = tf_.num[i + 1] * u - tf_.den[i + 1] * y + state_[i + 1];
    state_[Order - 1] = tf_.num[Order] * u - tf_.den[Order] * y;
    return y;
  }

  /// sum(num) / sum(den): the response to a constant input (den is stable, so sum(den) != 0).
  [[nodiscard]] double dc_gain() const noexcept {
    double n = 0.0, d = 0.0;
    for (std::size_t i = 0; i <= Order; ++i) { n += tf_.num[i]; d += tf_.den[i]; }
    return n / d;
  }

  /// Puts the states where a constant input u held forever would have left them, so a model that
  /// starts under a static load (gravity) starts without a switch-on transient.
  void settle(double u) noexcept {
    const double y = dc_gain() * u;
    double next = 0.0;
    for (std::size_t i = Order; i-- > 0;) {
      state_[i] = tf_.num[i + 1] * u - tf_.den[i + 1] * y + next;
      next = state_[i];
    }
  }

  /// The same filter as s(k+1) = A s(k) + B u(k), y(k) = s_0(k) + num[0] u(k); used to draw the
  /// initial state of a noise filter from its stationary distribution.
  void state_space(StateMatrix& a, StateVector& b) const {
    a.setZero();
    for (std::size_t i = 0; i < Order; ++i) {
      a(static_cast<Eigen::Index>(i), 0) = -tf_.den[i + 1];
      if (i + 1 < Order) a(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i + 1)) = 1.0;
      b(static_cast<Eigen::Index>(i)) = tf_.num[i + 1] - tf_.den[i + 1] * tf_.num[0];
    }
  }

  void set_state(const StateVector& s) noexcept {
    for (std::size_t i = 0; i < Order; ++i) state_[i] = s(static_cast<Eigen::Index>(i));
  }

  [[nodiscard]] const DiscreteTransferFunction<Order>& transfer_function() const noexcept { return tf_; }

 private:
  static_assert(Order >= 1, "a zero-order filter is a gain; no state to keep");
  DiscreteTransferFunction<Order> tf_{};
  std::array<double, Order> state_{};
};

}  // namespace inertia::sim
