#pragma once
// SI inside (m/s^2, rad/s, degC, s); g and degrees appear only at the edges (config, reports).
#include <numbers>

namespace inertia {

inline constexpr double kStandardGravity = 9.80665;  // m/s^2 per g (the paper's tables are in g)
inline constexpr double kPi = std::numbers::pi;

constexpr double deg_to_rad(double deg) { return deg * kPi / 180.0; }
constexpr double rad_to_deg(double rad) { return rad * 180.0 / kPi; }
constexpr double g_to_mps2(double g) { return g * kStandardGravity; }
constexpr double mps2_to_g(double mps2) { return mps2 / kStandardGravity; }

}  // namespace inertia
