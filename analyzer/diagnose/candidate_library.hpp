#pragma once
// The library of candidate effects the discrepancy workflow can name: every term of the paper's
// equations 1-6 and 12 (docs/design.md "Model terms"), evaluated on the residual of a model.
#include <vector>

#include "analyzer/ident/term.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::diagnose {

struct LibraryOptions {
  bool temperature = true;   // T, a_i*T (gyro: T, w_i*T, y*T); dropped when a case has no temp
  bool dynamics = true;      // lag-1 terms: inputs, their squares (high-pass K(s) a_j^2) and y[k-1]
  /// A small rotation of each mounting about each case axis (cases sharing a `mounting` label are
  /// one mounting), when the dataset declares mounting labels and has two or more mountings: a case misalignment the dataset's
  /// nominal m_ec does not hold is then named as such instead of as a spurious sensor term. With
  /// one mounting it is the model's own m_cs, which the terms a_p, a_o (w_p, w_o) already cover.
  bool mounting_rotations = true;
  /// The largest mounting rotation (deg) offered as a misalignment. The rotation columns are the
  /// linearised sensitivity, and a setup error of several degrees is a wrong nominal m_ec rather
  /// than a misalignment; past this bound the rotation stops being a model of the data and starts
  /// fitting whatever the given model lacks (a datasheet model on sim-paper took a rotation of
  /// tens of degrees; docs/validation.md, 'Evidence behind choices in the code').
  double max_rotation_deg = 5.0;
};

/// Accelerometer: 1, a_i, a_p, a_o (scale factor, cross-axis), a_i^2 a_p^2 a_o^2 (second order),
/// a_i*a_p a_i*a_o a_p*a_o (cross-coupling), abs(a_i) (rectification), a_i*abs(a_i) (odd
/// quadratic), sign(a_i) (asymmetry), T, a_i*T (temperature coefficients), a_i[k-1], a_i^2[k-1],
/// a_p^2[k-1], a_o^2[k-1], y[k-1] (dynamics).
/// Gyroscope: 1, w_i, w_p, w_o, w_i^2, w_i*abs(w_i) (scale-factor nonlinearity), a_i a_p a_o
/// (g-sensitivity), y*w_i (rational scale-factor nonlinearity, eq. 5), T, w_i*T, y*T, T[k-1],
/// w_i[k-1], a_i[k-1], y[k-1].
std::vector<ident::Term> candidate_library(dataset::SensorKind sensor, const LibraryOptions& options = {});

/// True when every case of `data` carries the columns `term` reads (T needs temp, w_* need rates).
bool dataset_supports(const dataset::Dataset& data, const ident::Term& term);

}  // namespace inertia::diagnose
