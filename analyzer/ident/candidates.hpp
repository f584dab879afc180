#pragma once
// Candidate term sets: the full models the paper starts algorithm 2 from.
//
// Accelerometer (section 2.4.1), model order r:
//   eq. 2 (frames F_E and F_S):  1, u_ES(k-l) for l = 0..r, y[k-1..k-r], e[k-1..k-r]
//   eq. 4 (frame F_S):           1, u_S(k-l)  for l = 0..r, y[k-1..k-r], e[k-1..k-r]
//   u_ES (eq. 1) = a_x a_y a_z a_i^2 a_p^2 a_o^2 a_i*a_p a_i*a_o a_p*a_o sign(a_i) abs(a_i) a_i*abs(a_i)
//   u_S  (eq. 3) = a_i         a_i^2 a_p^2 a_o^2 a_i*a_p a_i*a_o a_p*a_o sign(a_i) abs(a_i) a_i*abs(a_i)
//   optional temperature: T, a_i*T (current sample).
// Gyroscope (section 2.4.2), eqs. 5 (F_E and F_S) and 6 (F_S) made linear in the parameters by
// dividing by S_0 and moving the bracket's terms right (RME, section 2.6):
//   1 (D_F), w_x w_y w_z (eq. 5) or w_i (eq. 6), y*w_i (c_f1), a_i a_p a_o at lags 0..r (the
//   numerators of D/C, F/E, H/G), y[k-1..k-r] (their common denominators), e[k-1..k-r]
//   (B/A, the coloured noise); optional temperature: T, T[k-1] (c_T1, c_T2), y*T (epsilon_T).
// The paper's equation numbers are kept as printed; its prose swaps the captions of eqs. 5 and 6
// (eq. 5 holds w_x w_y w_z, so it is the F_E-and-F_S model).
#include <string>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::ident {

enum class ModelFrame {
  ExternalAndSensor,   // eqs. 2 / 5: the scale factor split over a_x a_y a_z (w_x w_y w_z), eq. 7
  Sensor,              // eqs. 4 / 6: everything in F_S
};

struct CandidateOptions {
  int r = 0;                          // model order: input lags 0..r, output (and noise) lags 1..r; 0 = static
  bool include_bias = true;           // the term "1"
  bool include_sign_abs = true;       // accelerometer: sign(a_i) abs(a_i) a_i*abs(a_i) (ignored for gyros)
  bool include_output_lags = true;    // y[k-1..k-r] (the ARX part; nothing when r = 0)
  bool include_noise_terms = false;   // e[k-1..k-r] (the MA part; needs an extended-least-squares estimator)
  bool include_temperature = false;   // accelerometer: T, a_i*T; gyro: T, T[k-1], y*T
  std::vector<std::string> exclude;   // terms to leave out, any spelling the grammar reads

  /// False (and why) when r is outside 0..kMaxLag.
  bool is_valid(std::string* why) const;
};

/// The candidate terms, in the order of the paper's equations: bias, then u(k), u(k-1), ...,
/// u(k-r), then y lags, then e lags, then temperature terms. Throws InputError for invalid
/// options, an unparsable exclusion or an exclusion that matches no candidate (a typo would
/// otherwise silently keep the term).
std::vector<Term> candidate_terms(dataset::SensorKind sensor, ModelFrame frame, const CandidateOptions& options);

/// Algorithm 2 step 7: the F_S counterpart of an F_E-and-F_S term set. Every factor in a_x, a_y,
/// a_z becomes a_i (w_x, w_y, w_z become w_i), keeping its lag, function and power; other terms
/// are unchanged. Terms that become equal are kept once, at the first position, so the selected
/// eq. 2 terms a_x, a_y, a_z map to the single eq. 4 term a_i (eq. 7: theta_x a_x + theta_y a_y +
/// theta_z a_z = theta_i a_i).
std::vector<Term> to_sensor_frame(const std::vector<Term>& terms);

}  // namespace inertia::ident
