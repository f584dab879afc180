#include "analyzer/procedure/batch_stage.hpp"

#include "analyzer/procedure/model_simulation.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <span>
#include <stdexcept>
#include <tuple>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/row_products.hpp"
#include "analyzer/ident/selection.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/procedure/batch_regression.hpp"
#include "analyzer/procedure/identifiable_fit.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/plan_validation.hpp"
#include "analyzer/procedure/post_selection_inference.hpp"
#include "analyzer/procedure/relative_twists.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/whitened_problem.hpp"
#include "common/units.hpp"

namespace inertia::procedure {
namespace {

using ident::Term;

/// One angle a mounting's excitation does not determine (excitation.hpp), held at the nominal
/// frame in blocks 5-6 and estimated in the batch with the tolerance as prior.
struct HeldColumn {
  std::size_t mounting = 0;                 // into the result's mountings
  /// The held turn's rotation-vector component (procedure::held_angle_response): 0 the twist about
  /// n_i (PipelineOptions::batch_relative_twist), 1 about p (a tilt of n_i toward o), 2 about o
  /// (toward p).
  int component = 2;
};

std::vector<HeldColumn> held_columns(const std::vector<MountingResult>& mountings) {
  std::vector<HeldColumn> held;
  for (std::size_t m = 0; m < mountings.size(); ++m) {
    const AxisExcitation& e = mountings[m].excitation;
    // Case axis XRA unexcited: the tilt toward p is not determined; YRA: the tilt toward o.
    if (!e.determined[1]) held.push_back({m, 2});
    if (!e.determined[2]) held.push_back({m, 1});
  }
  return held;
}

}  // namespace

BatchInnovation batch_innovation(const PipelineResult& result) {
  StackedRegression stack;
  stack.y = result.fit.residuals;
  stack.phi.resize(stack.y.size(), 0);
  for (const CaseOutcome& c : result.cases)
    if (c.rows > 0) stack.cases.push_back({c.case_index, c.begin, c.rows, c.first_row});
  std::sort(stack.cases.begin(), stack.cases.end(), [](const CaseRows& a, const CaseRows& b) { return a.begin < b.begin; });
  if (!result.rows_filtered) ArWhitener::of(result.whitening).apply(stack);
  const Eigen::Index dof = stack.y.size() - result.fit.theta.size();
  const double variance = dof > 0 ? stack.y.squaredNorm() / static_cast<double>(dof) : result.fit.residual_variance;
  return {std::move(stack.y), std::move(stack.cases), result.rows_filtered ? result.fit.residual_variance : variance};
}

BatchVerification batch_verification(const dataset::Dataset& data, const PipelineResult& result, std::string_view dataset_label) {
  BatchVerification v;
  v.innovation = batch_innovation(result);
  for (const CaseOutcome& outcome : result.cases) v.free_run.push_back(free_run_error(data, outcome, result, dataset_label));
  return v;
}

PipelineResult identify_batch(PipelineResult mounted, const dataset::Dataset& data, const PipelineOptions& options,
                              std::string_view dataset_label) {
  PipelineResult result = std::move(mounted);
  if (std::optional<std::string> note = temperature_note(data, options)) result.notes.push_back(std::move(*note));
  std::vector<Term> candidates = offered_terms(options.batch, ident::ModelFrame::Sensor, data, options, "batch");
  if (options.batch.select) {
    for (UndeterminedTerm& u : remove_unexcited_terms(candidates, data.cases, data.t_ref)) result.undetermined.push_back(std::move(u));
  }
  // Held angles (excitation.hpp) stay at the nominal frame; after the selection their tolerance
  // is propagated into the coefficients' covariance (below).
  const std::vector<HeldColumn> held = held_columns(result.mountings);
  const std::vector<Eigen::Vector3d> nominal(result.mountings.size(), Eigen::Vector3d::Zero());
  set_case_frames(data, result.mountings, nominal, result.cases);
  // The squares' high pass (eq. 12), its corner estimated on the whole batch as in blocks 5-6.
  WhitenedProblem whitened =
      whiten_problem(stack_regressions(candidates, batch_inputs(data, options, result.cases), data.t_ref, dataset_label), data,
                     whitening_options(options, options.square_highpass && options.batch_square_highpass, std::nullopt));
  result.square_corner_rad_s = whitened.square_corner_rad_s;
  result.whitening = whitened.whitener.coefficients();
  const std::optional<StaticNoiseLaw> batch_law = std::move(whitened.noise_law);
  const ArWhitener& whitener = whitened.whitener;
  // The batch's whitened regression rebuilt with the mountings turned or the corner moved: what the
  // searched parameters' derivatives and the held angles' refits need.
  const BatchRegression batch_at(data, options, dataset_label, ident::first_usable_row(candidates), whitener);
  RelativeTwists twists = relative_twists(std::move(whitened.regression), std::move(result.mountings), batch_at, candidates,
                                          result.square_corner_rad_s, data, options,
                                          batch_law ? batch_law->below_record(whitener) : std::function<double(double)>());
  const StackedRegression& filtered = twists.batch;
  result.mountings = std::move(twists.mountings);
  result.notes.insert(result.notes.end(), twists.notes.begin(), twists.notes.end());
  set_case_frames(data, result.mountings, nominal, result.cases);   // the cases' M_E^S with the turns

  // Block 10 or 11, the structure on the filtered rows.
  ident::UlsOptions uls = options.selection.uls;
  uls.noise_lags = options.batch.noise_lags;
  std::vector<Eigen::Index> columns;
  const std::vector<Eigen::Index> ranking = identifiable_ranking(filtered, data.sensor, options.selection.err);
  for (UndeterminedTerm& u : undetermined_columns(filtered, ranking)) result.undetermined.push_back(std::move(u));
  if (options.batch.select) {
    ident::SelectionOptions selection = options.selection;
    selection.uls.noise_lags = 0;   // structure first; the noise model joins the final fit
    ident::SelectionProblem problem{filtered.phi, filtered.y, filtered.labels, filtered.rational, ranking};
    problem.stretch_starts = stretch_starts(filtered.cases);
    // Every inertial sensor has a bias and a scale factor: the t-test of step 9 weighs the other
    // terms against them, never them against a candidate. Pruning the weaker of a near-collinear
    // pair first, it could take the bias out of the model and name a_p in its place (a_p's column
    // has a mean where the p axis' mean specific force is not zero; sim-gyro-thermal in
    // docs/validation.md, 'Evidence behind choices in the code').
    for (const Eigen::Index j : ident::sensitivities_then_bias(filtered.labels, data.sensor))
      if (std::find(ranking.begin(), ranking.end(), j) != ranking.end()) problem.kept.push_back(j);
    const ident::SelectionResult selected = ident::select_model(problem, selection, nullptr);
    columns = selected.best_model().columns;
  } else {
    columns = ranking;
  }
  // The selected model's coefficients and inference: on the filtered rows, or, with ULS's
  // output-multiplied terms (filters_rows), on the same rows unfiltered with the noise model in
  // the covariance. The candidates' columns keep their indices.
  result.rows_filtered = filters_rows(std::any_of(columns.begin(), columns.end(), [&](Eigen::Index c) {
    return std::find(filtered.rational.columns.begin(), filtered.rational.columns.end(), c) != filtered.rational.columns.end();
  }));
  const BatchRegression unfiltered_at(data, options, dataset_label, ident::first_usable_row(candidates), ArWhitener());
  const BatchRegression& rows_at = result.rows_filtered ? batch_at : unfiltered_at;
  std::optional<StackedRegression> unfiltered;
  if (!result.rows_filtered) unfiltered = unfiltered_at(candidates, result.mountings, nominal, result.square_corner_rad_s);
  const StackedRegression& batch = unfiltered ? *unfiltered : filtered;
  for (const CaseRows& rows : batch.cases) {
    CaseOutcome& c = result.cases[rows.case_index];
    c.first_row = rows.first_sample;
    c.begin = rows.begin;
    c.rows = rows.rows;
  }
  std::vector<std::string> dropped;
  ident::UlsResult selected_fit = fit_identifiable(batch, data.sensor, columns, uls, dropped);
  // Honest inference on the selected model (the selection's t-tests take every sample as
  // independent): (1) the cluster jackknife covariance over the cases' contiguous phases, where
  // it is larger (coloured residual within a phase, offsets between phases and cases, a model
  // error that repeats per phase, a term only a few phases carry), with Student's t on G - 1 dof; (2) each held angle turned by the
  // mounting tolerance moves the coefficients by d (the exact refit, nonlinear terms included),
  // and the covariance gains d d'. A term whose t then falls below the selection's level is not
  // determined by this plan: it leaves and the rest is refitted.
  const PhaseLayout layout = phase_layout(batch, candidates, data, result.cases, dataset_label);
  InferenceProblem honest;
  honest.s = &batch;
  honest.layout = &layout;
  honest.threshold = ident::family_threshold(options.selection.alpha, ranking.size());
  honest.may_remove = options.batch.select;
  honest.sensor = data.sensor;
  if (batch_law) honest.below_record = batch_law->below_record(whitener);
  if (!result.rows_filtered) honest.unfiltered_rows_ar = whitener.coefficients();
  // The searches whose results the batch's columns are built with: the squares' corner and each
  // mounting's determined angles (blocks 5-6, on the same samples). They join the Jacobian, so the
  // between-phase dof do not count the angles separately.
  struct Searched {
    std::size_t mounting = 0;
    int axis = 0;   // 0: the squares' corner; 1, 2, 3: the mounting's turn (turned(): tilts, twist)
  };
  std::vector<Searched> searches;
  if (result.square_corner_rad_s) searches.push_back({0, 0});
  for (std::size_t k = 0; k < result.mountings.size(); ++k)
    for (int axis = 1; axis < 3; ++axis)
      if (result.mountings[k].excitation.determined[static_cast<std::size_t>(axis)]) searches.push_back({k, axis});
  // The fitted prediction's derivative with respect to a searched parameter, as a whitened column.
  const auto searched_derivative = [&](const ident::UlsResult& fit, const Searched& search) {
    // A turn moves its mounting's cases only: the others are not built.
    const std::span<const std::size_t> moved_cases =
        search.axis > 0 ? std::span<const std::size_t>(result.mountings[search.mounting].cases) : std::span<const std::size_t>();
    const auto stack_at = [&](std::span<const Term> terms, double moved) {
      std::vector<Eigen::Vector3d> tilts = nominal;
      if (search.axis > 0) tilts[search.mounting](search.axis - 1) = moved;
      return rows_at.unwhitened(terms, result.mountings, tilts,
                                search.axis == 0 ? *result.square_corner_rad_s + moved : result.square_corner_rad_s, moved_cases);
    };
    // Steps: 1 % of the corner; 1e-4 rad of a turn (the columns are smooth in both).
    const double step = search.axis == 0 ? 1e-2 * *result.square_corner_rad_s : 1e-4;
    return prediction_derivative(fit, step, rows_at.whitener(), batch.cases, stack_at);
  };
  honest.searched = [&](const ident::UlsResult& fit) {
    SearchedColumns out;
    Eigen::MatrixXd& columns = out.derivatives;
    columns.resize(batch.phi.rows(), 0);
    for (std::size_t i = 0; i < searches.size(); ++i) {
      if (searches[i].axis == 0 && !has_square_term(fit)) continue;
      columns.conservativeResize(Eigen::NoChange, columns.cols() + 1);
      columns.col(columns.cols() - 1) = searched_derivative(fit, searches[i]);
      out.ids.push_back(i);
    }
    return out;
  };
  // The cases' stated placements, and each twist the batch estimated (relative_twists), are
  // known parts of the residual's covariance: what a turn by its sd moves the fit's prediction.
  // A twist's sd is its search's, with every candidate term free. As a column of the Jacobian it
  // would be re-estimated with the selected terms alone, and the selection leaves out the terms it
  // is collinear with: then the twist looks determined where the plan does not determine it, and
  // the terms it absorbs miss the truth far beyond their sd (docs/validation.md, 'Long rests').
  const std::vector<StatedPlacement> placements = stated_placements(data);
  if (!placements.empty() || !twists.estimated.empty()) {
    honest.placements = [&](const ident::UlsResult& fit) {
      std::vector<Term> terms;
      for (Eigen::Index j = 0; j < fit.process_terms; ++j) terms.push_back(ident::parse_term(fit.labels[std::size_t(j)]));
      Eigen::MatrixXd columns = placements.empty() ? Eigen::MatrixXd(batch.phi.rows(), 0)
                                                   : rows_at.placement_columns(terms, fit.theta.head(fit.process_terms), result.mountings,
                                                                               nominal, result.square_corner_rad_s, placements);
      for (std::size_t k : twists.estimated) {
        columns.conservativeResize(Eigen::NoChange, columns.cols() + 1);
        columns.col(columns.cols() - 1) = twists.twist_sd_rad[k] * searched_derivative(fit, {k, 3});
      }
      return columns;
    };
  }
  // Held angles and held twists: each turned by the tolerance moves the coefficients by d.
  std::vector<HeldColumn> held_turns = held;
  for (std::size_t k : twists.held) held_turns.push_back({k, 0});
  if (!held_turns.empty() && options.mounting_tolerance_rad > 0.0) {
    honest.held_covariance = [&](const ident::UlsResult& fit) {
      const Eigen::Index p = fit.process_terms;
      Eigen::MatrixXd held_part = Eigen::MatrixXd::Zero(p, p);
      std::vector<Term> terms;
      for (Eigen::Index j = 0; j < p; ++j) terms.push_back(ident::parse_term(fit.labels[std::size_t(j)]));
      // A turned mounting changes its own cases' rows alone. Where the terms are linear least
      // squares (no output-multiplied column, no noise lags), the refit takes the batch's normal
      // equations with that mounting's share replaced by its turned rows', and the other cases
      // are not built again.
      std::vector<Eigen::Index> stack_columns;
      for (Eigen::Index j = 0; j < p; ++j)
        stack_columns.push_back(std::find(batch.labels.begin(), batch.labels.end(), fit.labels[std::size_t(j)]) - batch.labels.begin());
      const bool linear = uls.noise_lags == 0 && std::none_of(stack_columns.begin(), stack_columns.end(), [&](Eigen::Index c) {
        return std::find(batch.rational.columns.begin(), batch.rational.columns.end(), c) != batch.rational.columns.end();
      });
      // X'X and X'y of the terms' columns over rows [begin, begin + rows) of the batch, a block of
      // rows at a time (the columns are not contiguous in the stack, and a copy of them all would
      // be the size of the fit's stack again).
      const auto normal_equations = [&](Eigen::Index begin, Eigen::Index rows) {
        constexpr Eigen::Index kBlockRows = 16384;
        std::pair<Eigen::MatrixXd, Eigen::VectorXd> out{Eigen::MatrixXd::Zero(p, p), Eigen::VectorXd::Zero(p)};
        for (Eigen::Index at = begin; at < begin + rows; at += kBlockRows) {
          const Eigen::Index n = std::min(kBlockRows, begin + rows - at);
          const Eigen::MatrixXd x = batch.phi.middleRows(at, n)(Eigen::all, stack_columns);
          out.first += ident::gram(x);
          out.second += ident::cross_product(x, batch.y.segment(at, n));
        }
        return out;
      };
      Eigen::MatrixXd gram_all;
      Eigen::VectorXd cross_all;
      if (linear) std::tie(gram_all, cross_all) = normal_equations(0, batch.phi.rows());
      for (const HeldColumn& h : held_turns) {
        const std::optional<Eigen::VectorXd> d = held_angle_response(
            fit.theta.head(p), h.component, options.mounting_tolerance_rad,
            [&](const Eigen::Vector3d& turn) -> std::optional<Eigen::VectorXd> {
              std::vector<Eigen::Vector3d> tilts = nominal;
              tilts[h.mounting] = turn;
              if (linear) {
                const std::vector<std::size_t>& moved = result.mountings[h.mounting].cases;
                StackedRegression turned = rows_at.unwhitened(terms, result.mountings, tilts, result.square_corner_rad_s, moved);
                rows_at.whitener().apply(turned);
                Eigen::MatrixXd gram = gram_all;
                Eigen::VectorXd cross = cross_all;
                for (const CaseRows& built : turned.cases) {
                  const auto at = std::find_if(batch.cases.begin(), batch.cases.end(),
                                               [&](const CaseRows& r) { return r.case_index == built.case_index; });
                  if (at == batch.cases.end() || at->rows != built.rows)
                    throw std::logic_error("held angle refit: the turned mounting's rows are not the batch's");
                  const auto [gram_was, cross_was] = normal_equations(at->begin, at->rows);
                  const auto now = turned.phi.middleRows(built.begin, built.rows);
                  gram += ident::gram(now) - gram_was;
                  cross += ident::cross_product(now, turned.y.segment(built.begin, built.rows)) - cross_was;
                }
                return Eigen::VectorXd(gram.ldlt().solve(cross));
              }
              const StackedRegression s = rows_at(terms, result.mountings, tilts, result.square_corner_rad_s);
              std::vector<Eigen::Index> all(terms.size());
              for (std::size_t j = 0; j < all.size(); ++j) all[j] = static_cast<Eigen::Index>(j);
              return ident::uls_coefficients(s.phi, s.y, s.labels, s.rational, uls, all).head(p);
            });
        if (d) held_part += *d * d->transpose();
      }
      return held_part;
    };
  }
  InferenceOutcome inference = infer_after_selection(honest, std::move(columns), std::move(selected_fit), uls);
  for (const PrunedTerm& pruned : inference.pruned) result.undetermined.push_back({pruned.term, pruned_reason(pruned, "batch model")});
  columns = std::move(inference.columns);
  result.fit = std::move(inference.fit);
  if (!held.empty() && options.batch.select) {
    // Held angles leave the model in a frame that is not the sensor's. A turn within the tolerance
    // is allowed for above; a misfit the model cannot absorb shows as an innovation that still
    // follows the sensitive input. Then the frame-dependent terms (everything but the bias, the
    // scale factor and temperature terms) are not determined by this plan: they leave.
    const auto input_column = std::find_if(batch.labels.begin(), batch.labels.end(),
                                           [](const std::string& l) { return l == "a_i" || l == "w_i"; });
    const bool none_aligned =
        std::none_of(result.mountings.begin(), result.mountings.end(), [](const MountingResult& m) { return m.aligned; });
    const BatchInnovation innovation = batch_innovation(result);   // the filtered rows' layout
    if (input_column != batch.labels.end() && filtered.phi.rows() == innovation.values.size()) {
      const ident::CorrelationCheck check = ident::residual_input_correlation(
          innovation.values, filtered.phi.col(input_column - batch.labels.begin()), 20);
      if (!check.pass || none_aligned) {
        // Linear in the sensitive input (times temperature, output or lags) holds in any frame near
        // the sensor's; squares, |a_i|, sign and the cross-axis inputs do not.
        std::vector<Eigen::Index> kept;
        for (Eigen::Index c : columns) {
          const std::string& label = batch.labels[static_cast<std::size_t>(c)];
          if (frame_free(ident::parse_term(label))) {
            kept.push_back(c);
          } else {
            result.undetermined.push_back(
                {label, none_aligned
                            ? std::string("not determined by this plan: no mounting is aligned, so the sensor frame's p and o "
                                          "axes are not known in any case and a term that depends on them has no frame; an "
                                          "aligned mounting (a table or tumble case, or one mounting label shared by the "
                                          "shaker orientations) determines them")
                            : fmt::format("not determined by this plan: the held mounting angles leave a misfit the model "
                                          "cannot absorb (the innovation still follows the sensitive input: {} of {} lags "
                                          "outside the 95 % band), so the terms that depend on the sensor frame's p and o "
                                          "axes are not known; an aligned mounting determines them",
                                          check.outside, check.lags.size())});
          }
        }
        if (kept.size() < columns.size()) {
          columns = kept;
          honest.may_remove = false;
          ident::UlsResult frame_free_fit = fit_identifiable(batch, data.sensor, columns, uls, dropped);
          inference = infer_after_selection(honest, std::move(columns), std::move(frame_free_fit), uls);
          columns = std::move(inference.columns);
          result.fit = std::move(inference.fit);
        }
      }
    }
  }
  result.inference = inference.offsets;
  if (!placements.empty()) {
    const auto [least, most] = std::minmax_element(placements.begin(), placements.end(), [](const StatedPlacement& a, const StatedPlacement& b) {
      return a.sd_rad < b.sd_rad;
    });
    const double p_value = inference.offsets.stated_offsets_p;
    result.notes.push_back(fmt::format(
        "{} case(s) state their placement ({:.3f} to {:.3f} deg per axis, placement_sd_deg): a known part of the residual's "
        "covariance, in every sd; {}",
        placements.size(), rad_to_deg(least->sd_rad), rad_to_deg(most->sd_rad),
        !std::isfinite(p_value) ? std::string("too few phases to test for offsets between them beyond that")
        : p_value >= ident::kStatedOffsetsLevel
            ? fmt::format("the offsets between phases are what the noise and the placements explain (p = {:.2f})", p_value)
            : fmt::format("the offsets between phases exceed what the noise and the placements explain (p = {:.2g}), and the "
                          "excess is in the sd",
                          p_value)));
  }
  result.test_dof = inference.dof;
  const Eigen::MatrixXd& held_part = inference.held_covariance;
  result.held_sd = held_part.rows() == result.fit.process_terms ? Eigen::VectorXd(held_part.diagonal().cwiseMax(0.0).cwiseSqrt())
                                                                  : Eigen::VectorXd::Zero(result.fit.process_terms);
  // The angles the batch refined (relative_twists) get their sd from its joint covariance.
  for (std::size_t c = 0; c < inference.searched_ids.size() && static_cast<Eigen::Index>(c) < inference.searched_covariance.rows(); ++c) {
    const Searched& search = searches[inference.searched_ids[c]];
    if (search.axis == 0 || std::find(twists.estimated.begin(), twists.estimated.end(), search.mounting) == twists.estimated.end())
      continue;
    const auto i = static_cast<Eigen::Index>(c);
    result.mountings[search.mounting].angles_sd(angle_of_turn(search.axis - 1)) =
        std::sqrt(std::max(0.0, inference.searched_covariance(i, i)));
  }
  for (std::size_t k : twists.estimated) {
    MountingResult& m = result.mountings[k];
    m.angles_sd(0) = twists.twist_sd_rad[k];
    result.notes.push_back(fmt::format("mounting '{}' is turned {:+.4f} +- {:.4f} deg about n_i against '{}' (found in the batch, "
                                       "with its tilts: one set of cross-axis terms holds in both; the sensor's p and o axes "
                                       "are those of '{}''s nominal frame, as algorithm 1 takes them)",
                                       m.mounting, rad_to_deg(m.angles(0)), rad_to_deg(m.angles_sd(0)), m.twist_reference,
                                       m.twist_reference));
  }
  if (!held_turns.empty() && options.mounting_tolerance_rad > 0.0) {
    result.notes.push_back(fmt::format("{} mounting angle(s) held at the nominal case frame; each is assumed within "
                                       "+-{:.2f} deg (--mounting-tolerance-deg), and what that moves is in the sd",
                                       held_turns.size(), rad_to_deg(options.mounting_tolerance_rad)));
  }
  result.terms = ident::parse_terms(result.fit.process_labels());
  result.t_test = ident::parameter_t_test(result.fit.process_theta(), result.fit.std_dev.head(result.fit.process_terms),
                                          result.fit.residuals.size());
  for (Eigen::Index j = 0; j < result.t_test.p_value.size() && j < result.test_dof.size(); ++j) {
    result.t_test.p_value(j) = ident::student_t_two_sided_p(result.t_test.t(j), result.test_dof(j));
  }
  result.residual_mean = ident::residual_mean_test(result.fit.residuals, stretch_starts(batch.cases));
  result.aic = ident::aic(result.fit.residuals, result.fit.theta.size());
  return result;
}

Eigen::VectorXd free_run_error(const dataset::Dataset& data, const CaseOutcome& outcome, const PipelineResult& result,
                               std::string_view dataset_label) {
  const dataset::CaseData& c = data.cases[outcome.case_index];
  const ident::SignalSet signals = ident::signals_from_case(c, outcome.m_es, data.t_ref, dataset_label);
  const Eigen::Index first = ident::first_usable_row(result.terms);
  if (first >= c.size()) return {};
  return simulate_model(result.terms, result.fit.process_theta(), signals, first, result.square_corner_rad_s, c.sample_period_s) -
         c.y.tail(c.size() - first);
}

}  // namespace inertia::procedure
