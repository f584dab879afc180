#pragma once
// The discrepancy workflow: simulate a model on the measured references, locate where
// the residual exceeds the noise the model claims, name the missing effect from a library of
// candidate terms (ERR on the residual, then a t-test with honest standard deviations and AIC),
// add it, re-estimate, re-simulate, repeat until no candidate is significant.
#include <Eigen/Dense>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/diagnose/candidate_library.hpp"
#include "analyzer/diagnose/location.hpp"
#include "analyzer/model/model_file.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::diagnose {

struct DiagnoseOptions {
  /// Family-wise significance level of one search step: the winner's t-test runs at alpha / m,
  /// m = candidates ranked (Bonferroni), since the winner is the best of m, and its own p-value
  /// is optimistic; this keeps the false-alarm probability of a step at most alpha.
  double alpha = 0.05;
  int max_findings = 8;
  /// The ERR-ranked candidates whose t-value is computed; the most significant of them wins.
  /// Why more than one: under coloured residuals a slow spurious column can top the ERR ranking
  /// (ERR weighs low-frequency power), while the prewhitened t-test sees through it.
  int contenders = 3;
  /// AR prewhitening order limit (AIC picks the order, 0 = white). Each order costs one lagged
  /// Gram pass over the data (O(N p^2)), so it bounds the run time; 12 whitens pink noise well.
  int max_ar_order = 12;
  LibraryOptions library;
};

/// Residual RMS of one case and phase, and the location test against the noise reference.
struct SegmentStats {
  std::size_t case_index = 0;
  std::string phase;          // "all" when the case has no phase column
  Eigen::Index samples = 0;
  double rms = 0.0;
  double ratio = 0.0;         // rms / noise reference
  double p_value = 1.0;       // chi-square (or F) upper tail: P(this much power | model noise)
  bool excess = false;        // p below alpha / number of segments
};

struct ResidualSummary {
  std::string label;                 // "baseline", "+ a_i*a_p", ...
  double overall = 0.0;              // RMS over every residual sample
  std::vector<double> per_case;      // RMS per case
  std::vector<SegmentStats> segments;
};

struct Finding {
  std::string term;                  // canonical
  std::string effect;                // physical name
  double coefficient = 0.0;          // at the step it was found (what its test saw)
  /// In the final augmented model, every finding refitted together: with several effects
  /// missing, the first step's coefficient also carries what later findings explain.
  double final_coefficient = 0.0, final_std = 0.0;
  double std = 0.0;                  // prewhitened (GLS) standard deviation
  double t = 0.0;
  double p_value = 1.0;              // two-sided, Student's t
  double threshold_p = 0.0;          // alpha / m it had to beat
  double err = 0.0;                  // ERR on the residual at its step
  double delta_aic = 0.0;            // AIC(with) - AIC(without), negative = better
  int ar_order = 0;                  // prewhitening order of the fit
  std::string where_case, where_phase;   // segment where its contribution is largest (RMS)
  double where_rms = 0.0;
  /// A mounting rotation (case misalignment) rather than a sensor term: the mounting, its cases,
  /// the case axis (0 x, 1 y, 2 z), and the mounting's total rotation about it after the search
  /// with its sd (coefficient and std are then the angle increment of its step, rad).
  std::string mounting;
  std::vector<std::string> mounting_cases;
  int axis = -1;
  double angle_deg = 0.0, angle_std_deg = 0.0;
};

struct DiagnoseResult {
  model::ModelFile baseline;
  model::ModelFile final_model;
  std::vector<std::string> case_names;
  std::vector<std::string> library;        // canonical candidate terms the search used
  std::vector<ResidualSummary> steps;      // steps[0] = baseline, then one per finding
  /// The given terms only, re-estimated (ULS, held terms kept): how much of the baseline gap is
  /// coefficient error rather than a missing effect. Absent when that fit is impossible.
  std::optional<ResidualSummary> refit_only;
  std::vector<Finding> findings;           // sensor effects, in the order found
  /// Mounting rotations the search accepted (in the order found, interleaved with the findings in
  /// `steps`): a case misalignment the dataset's nominal m_ec lacks, named as such.
  std::vector<Finding> case_misalignments;
  /// Set when the given model had no squares and no high pass, and the squares found act through
  /// eq. 12's high pass: its corner (rad/s), estimated from the data and written to the model.
  std::optional<double> estimated_square_corner_rad_s;
  std::vector<std::string> held_fixed;     // model terms the data cannot estimate (kept as given)
  double noise_reference = 0.0;            // the sd the location test compares with
  std::string location_test;               // which test: chi-square vs white_sd, or F vs final
  /// Per case: time of each residual row, residual before and after (for plots).
  std::vector<Eigen::VectorXd> time, residual_before, residual_after;
  std::vector<std::vector<std::uint16_t>> phase;   // per residual row, index into the case's names
  std::vector<Eigen::Index> first_sample;          // per case: the case sample of residual row 0
  /// Where the residual exceeds the model's noise by frequency band and by condition, before
  /// (baseline model and its noise) and after (final model).
  Location location_before, location_after;
};

/// Runs the workflow. Throws InputError when the model is for another sensor kind than the
/// dataset, or when a case lacks a column one of the model's terms needs (naming term, column,
/// case). `dataset_label` names the dataset in messages.
DiagnoseResult diagnose(const dataset::Dataset& data, const model::ModelFile& model, const DiagnoseOptions& options,
                        const std::string& dataset_label);

}  // namespace inertia::diagnose
