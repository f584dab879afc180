#include "analyzer/procedure/post_selection_inference.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <stdexcept>

#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/row_products.hpp"
#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/procedure/identifiable_fit.hpp"
#include "analyzer/procedure/prewhitening.hpp"

namespace inertia::procedure {
namespace {

using ident::Term;

/// True when `c` is a piece of the plan case whose rows the stack holds just before it
/// (CaseData::piece_of): a few lost samples cut neither its noise process nor its phases.
bool continues_plan_case(const dataset::CaseData& c, const std::string* previous_plan_case) {
  return previous_plan_case != nullptr && !c.piece_of.empty() && *previous_plan_case == c.plan_case();
}

}  // namespace

std::vector<int> phase_clusters(const StackedRegression& s, const dataset::Dataset& data) {
  std::vector<int> ids(static_cast<std::size_t>(s.phi.rows()), -1);
  int next = 0;
  const std::string* previous_case = nullptr;
  std::string previous_phase;
  for (const CaseRows& rows : s.cases) {
    const dataset::CaseData& c = data.cases[rows.case_index];
    const bool continues = continues_plan_case(c, previous_case);
    for (Eigen::Index r = 0; r < rows.rows; ++r) {
      const auto sample = static_cast<std::size_t>(rows.first_sample + r);
      const std::string& phase = c.phase.empty() ? c.plan_case() : c.phase_names[c.phase[sample]];
      if ((r == 0 && !continues) || phase != previous_phase) ++next;
      previous_phase = phase;
      ids[static_cast<std::size_t>(rows.begin + r)] = next;
    }
    if (rows.rows > 0) previous_case = &c.plan_case();
  }
  return ids;
}

std::vector<CaseRows> plan_case_rows(const StackedRegression& s, const dataset::Dataset& data) {
  std::vector<CaseRows> out;
  const std::string* previous_case = nullptr;
  for (const CaseRows& rows : s.cases) {
    const dataset::CaseData& c = data.cases[rows.case_index];
    if (rows.rows == 0) continue;
    if (continues_plan_case(c, previous_case) && out.back().begin + out.back().rows == rows.begin) {
      out.back().rows += rows.rows;
    } else {
      out.push_back(rows);
    }
    previous_case = &c.plan_case();
  }
  return out;
}

Eigen::VectorXd cross_axis_loading(const StackedRegression& whitened, std::span<const Term> candidates,
                                   const dataset::Dataset& data, const std::vector<CaseOutcome>& cases,
                                   std::string_view label) {
  const bool gyro = data.sensor == dataset::SensorKind::Gyroscope;
  const std::vector<Term> cross = ident::parse_terms(gyro ? std::vector<std::string>{"w_p", "w_o"} : std::vector<std::string>{"a_p", "a_o"});
  std::vector<StackInput> inputs;
  for (const CaseRows& rows : whitened.cases) inputs.push_back({rows.case_index, &data.cases[rows.case_index], cases[rows.case_index].m_es, 1.0, {}});
  const StackedRegression raw = stack_regressions(cross, inputs, data.t_ref, label, ident::first_usable_row(candidates));
  Eigen::VectorXd out(whitened.phi.rows());
  for (std::size_t c = 0; c < whitened.cases.size(); ++c) {
    const CaseRows& w = whitened.cases[c];
    const CaseRows& r = raw.cases[c];
    const Eigen::Index skip = r.rows - w.rows;   // the whitener's first rows
    if (skip < 0 || r.case_index != w.case_index) throw std::logic_error("cross_axis_loading: layouts differ");
    out.segment(w.begin, w.rows) = raw.phi.middleRows(r.begin + skip, w.rows).rowwise().squaredNorm();
  }
  return out;
}

Eigen::VectorXd prediction_derivative(const ident::UlsResult& fit, double step, const ArWhitener& whitener,
                                      const std::vector<CaseRows>& layout,
                                      const std::function<StackedRegression(std::span<const Term>, double)>& stack_at) {
  const Eigen::Index p = fit.process_terms;
  const std::vector<Term> terms = ident::parse_terms(fit.process_labels());
  // One rebuilt regression at a time: each is reduced to its prediction before the next is built.
  StackedRegression difference;
  {
    const StackedRegression up = stack_at(terms, step);
    difference.y.noalias() = up.phi * fit.theta.head(p);
    difference.cases = up.cases;
  }
  {
    const StackedRegression down = stack_at(terms, -step);
    if (down.phi.rows() != difference.y.size()) throw std::logic_error("prediction_derivative: the two rebuilt regressions differ in rows");
    difference.y.noalias() -= down.phi * fit.theta.head(p);
  }
  difference.y /= 2.0 * step;
  difference.phi.resize(difference.y.size(), 0);
  whitener.apply(difference);
  // Each built case's rows to its place in the layout; a case not built did not move.
  Eigen::VectorXd out = Eigen::VectorXd::Zero(layout.empty() ? 0 : layout.back().begin + layout.back().rows);
  for (const CaseRows& built : difference.cases) {
    const auto at = std::find_if(layout.begin(), layout.end(), [&](const CaseRows& r) { return r.case_index == built.case_index; });
    if (at == layout.end() || at->rows != built.rows)
      throw std::logic_error("prediction_derivative: the rebuilt regression's rows are not the fit's");
    out.segment(at->begin, at->rows) = difference.y.segment(built.begin, built.rows);
  }
  return out;
}

noise::SegmentSpectrum residual_spectrum(const Eigen::Ref<const Eigen::VectorXd>& run, const Eigen::VectorXd& ar,
                                         const std::function<double(double)>& below_record) {
  if (ar.size() == 0 || run.size() <= ar.size()) return noise::fitted_spectrum(run, below_record);
  Eigen::VectorXd innovation(run.size() - ar.size());
  ar_filter(ar, run, innovation);
  return noise::fitted_spectrum_through_ar(innovation, ar, run.size(), below_record);
}

double unfiltered_long_run_ratio(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& runs, const Eigen::VectorXd& ar) {
  double long_run = 0.0, power = 0.0;
  for (const CaseRows& rows : runs) {
    if (rows.rows < 2) continue;
    const auto run = residuals.segment(rows.begin, rows.rows);
    // 1'R1: the run's rows as one group, its noise sum's variance from the autocovariance.
    const noise::RowGroups whole{std::vector<Eigen::Index>(static_cast<std::size_t>(rows.rows), 0), 1};
    long_run += noise::group_covariance(residual_spectrum(run, ar), whole)(0, 0);
    power += run.squaredNorm();
  }
  return power > 0.0 && std::isfinite(long_run) ? std::max(1.0, long_run / power) : 1.0;
}

PhaseLayout phase_layout(const StackedRegression& s, std::span<const Term> candidates, const dataset::Dataset& data,
                         const std::vector<CaseOutcome>& cases, std::string_view label) {
  return {phase_clusters(s, data), plan_case_rows(s, data), cross_axis_loading(s, candidates, data, cases, label)};
}

std::string pruned_reason(const PrunedTerm& pruned, std::string_view model) {
  if (pruned.saturated) {
    return fmt::format("left out of the {} after selection: it had as many parameters at the level of the {} phases' means "
                       "as there are phases, so the offsets between them (placement, drift) could not be told from it; this "
                       "was its weakest (t {:.1f})",
                       model, pruned.phases, pruned.t);
  }
  return fmt::format("left out of the {} after selection: t {:.1f} on {:.0f} dof, with the offsets between its {} phases{}, "
                     "is below the selection's level",
                     model, pruned.t, pruned.dof, pruned.phases, pruned.with_held_angles ? " and the held angles" : "");
}

InferenceOutcome infer_after_selection(const InferenceProblem& h, std::vector<Eigen::Index> columns,
                                       ident::UlsResult fit, const ident::UlsOptions& uls) {
  const StackedRegression& s = *h.s;
  std::vector<PrunedTerm> pruned;
  std::vector<std::string> dropped;
  // The whitened residual's own noise model per case of the plan (its low-frequency colour:
  // coloured_noise.hpp), fitted once on the selected model's residual: a term that leaves takes its
  // column of the meat X'RX with it, and the residual it leaves behind differs by a term that
  // tested as nothing.
  std::vector<noise::SegmentSpectrum> spectra;
  std::vector<noise::RowGroups> run_phases;                 // per noise run: each row's phase within it
  std::vector<std::vector<Eigen::Index>> run_phase_columns;  // per noise run: its phases' columns of Z
  ident::ColouredNoise coloured;
  // X'RX of the terms' columns. The stack and the spectra stay over the loop, so a term that leaves
  // only takes its row and column away: the block is transformed once, for the stack's columns
  // `meat_columns`, and each round takes its terms' part of it. Only the searched columns, which
  // follow the fit, are new each round.
  Eigen::MatrixXd noise_sums_covariance;   // Z'RZ of the noise alone
  std::vector<Eigen::Index> meat_columns;
  Eigen::MatrixXd terms_meat;
  Eigen::MatrixXd stack_gram;              // the stack's columns' Gram, of which the terms' is a part
  for (;;) {
    InferenceOutcome out;
    const auto finish = [&]() {
      out.columns = std::move(columns);
      out.fit = std::move(fit);
      out.pruned = std::move(pruned);
      return std::move(out);
    };
    const Eigen::Index p = fit.process_terms;
    out.dof = Eigen::VectorXd::Constant(p, static_cast<double>(fit.residuals.size() - p - 1));
    if (s.phi.rows() != fit.residuals.size() || p == 0) return finish();
    Eigen::MatrixXd searched;
    if (h.searched) {
      SearchedColumns columns_searched = h.searched(fit);
      searched = std::move(columns_searched.derivatives);
      out.searched_ids = std::move(columns_searched.ids);
    }
    if (searched.cols() == 0) searched.resize(s.phi.rows(), 0);
    if (searched.rows() != s.phi.rows()) throw std::logic_error("infer_after_selection: searched columns of another stack");
    // X = [the terms' columns of the stack in the fit's linear form, the searched parameters'
    // derivatives] is never copied whole (it would hold the terms' part of the stack again): the
    // sums below read the stack's columns in place and keep the terms' rows of what they give.
    std::vector<Eigen::Index> output_multiplied;
    std::vector<Eigen::Index> stack_columns(static_cast<std::size_t>(p));   // each term's column of the stack
    for (Eigen::Index j = 0; j < p; ++j) {
      const auto column = static_cast<Eigen::Index>(std::find(s.labels.begin(), s.labels.end(), fit.labels[std::size_t(j)]) -
                                                    s.labels.begin());
      if (std::find(s.rational.columns.begin(), s.rational.columns.end(), column) != s.rational.columns.end()) output_multiplied.push_back(j);
      stack_columns[std::size_t(j)] = column;
    }
    const Eigen::VectorXd signs = ident::linear_form_signs(p, output_multiplied);   // the linear form
    // The terms' rows, in the linear form, of something with one row per column of the stack.
    const auto terms_rows = [&](const Eigen::MatrixXd& per_stack_column) -> Eigen::MatrixXd {
      return signs.asDiagonal() * per_stack_column(stack_columns, Eigen::all);
    };
    const Eigen::Index n_searched = searched.cols();
    // Rows [begin, begin + block.rows()) of X.
    const auto fill_x = [&](Eigen::Index begin, Eigen::Ref<Eigen::MatrixXd> block) {
      for (Eigen::Index j = 0; j < p; ++j) block.col(j) = signs(j) * s.phi.col(stack_columns[std::size_t(j)]).segment(begin, block.rows());
      block.rightCols(n_searched) = searched.middleRows(begin, block.rows());
    };
    const ident::RowBlocks x_blocks{s.phi.rows(), p + n_searched, fill_x};
    if (spectra.empty()) {
      std::map<int, Eigen::Index> order;   // cluster id -> column of Z (ascending ids)
      for (const int id : h.layout->clusters) order.emplace(id, 0);
      for (auto& [id, column] : order) {
        column = static_cast<Eigen::Index>(coloured.cluster_ids.size());
        coloured.cluster_ids.push_back(id);
      }
      const auto g_count = static_cast<Eigen::Index>(order.size());
      coloured.sums_covariance = Eigen::MatrixXd::Zero(g_count, g_count);
      for (const CaseRows& rows : h.layout->noise_runs) {
        spectra.push_back(residual_spectrum(fit.residuals.segment(rows.begin, rows.rows), h.unfiltered_rows_ar, h.below_record));
        // The covariance of the sums of this case's phases (each phase a run of rows within it).
        std::vector<Eigen::Index>& columns = run_phase_columns.emplace_back();
        noise::RowGroups& phases = run_phases.emplace_back();
        phases.group.resize(static_cast<std::size_t>(rows.rows));
        for (Eigen::Index k = 0; k < rows.rows; ++k) {
          const Eigen::Index g = order.at(h.layout->clusters[static_cast<std::size_t>(rows.begin + k)]);
          auto at = std::find(columns.begin(), columns.end(), g);
          if (at == columns.end()) at = columns.insert(columns.end(), g);
          phases.group[static_cast<std::size_t>(k)] = at - columns.begin();
        }
        phases.groups = static_cast<Eigen::Index>(columns.size());
        const Eigen::MatrixXd zrz = noise::group_covariance(spectra.back(), phases);
        for (std::size_t a = 0; a < columns.size(); ++a)
          for (std::size_t b = 0; b < columns.size(); ++b) coloured.sums_covariance(columns[a], columns[b]) = zrz(Eigen::Index(a), Eigen::Index(b));
      }
      noise_sums_covariance = coloured.sums_covariance;
    }
    // The stated placements' part of R, P P' (InferenceProblem::placements), as the fit now predicts.
    Eigen::MatrixXd placed;
    if (h.placements) placed = h.placements(fit);
    if (placed.cols() > 0 && placed.rows() != s.phi.rows()) throw std::logic_error("infer_after_selection: placements of another stack");
    // R m for columns m over the stack's rows: each case of the plan under its own spectrum.
    const auto noise_times = [&](const Eigen::Ref<const Eigen::MatrixXd>& m) {
      Eigen::MatrixXd out = Eigen::MatrixXd::Zero(m.rows(), m.cols());
      for (std::size_t r = 0; r < spectra.size(); ++r) {
        const CaseRows& run = h.layout->noise_runs[r];
        out.middleRows(run.begin, run.rows) = noise::covariance_times(spectra[r], m.middleRows(run.begin, run.rows));
      }
      return out;
    };
    // X'RX and X'RZ, case by case (R is block diagonal over the noise runs).
    std::vector<Eigen::Index> in_meat;   // each term's row of terms_meat
    for (const Eigen::Index column : stack_columns) {
      const auto at = std::find(meat_columns.begin(), meat_columns.end(), column);
      if (at == meat_columns.end()) break;
      in_meat.push_back(at - meat_columns.begin());
    }
    if (static_cast<Eigen::Index>(in_meat.size()) != p) {
      meat_columns = stack_columns;
      terms_meat = Eigen::MatrixXd::Zero(p, p);
      for (std::size_t r = 0; r < spectra.size(); ++r) {
        const CaseRows& run = h.layout->noise_runs[r];
        terms_meat += noise::quadratic_form(spectra[r], s.phi.middleRows(run.begin, run.rows), stack_columns);
      }
      terms_meat = signs.asDiagonal() * terms_meat * signs.asDiagonal();
      in_meat.resize(static_cast<std::size_t>(p));
      std::iota(in_meat.begin(), in_meat.end(), Eigen::Index{0});
    }
    const Eigen::Index q = n_searched;
    coloured.meat = Eigen::MatrixXd::Zero(p + q, p + q);
    coloured.meat.topLeftCorner(p, p) = terms_meat(in_meat, in_meat);
    if (q > 0) {
      // X'R S and S'R S a noise run at a time: R S for one run's rows, not for the stack's.
      Eigen::MatrixXd stack_searched = Eigen::MatrixXd::Zero(s.phi.cols(), q), searched_meat = Eigen::MatrixXd::Zero(q, q);
      for (std::size_t r = 0; r < spectra.size(); ++r) {
        const CaseRows& run = h.layout->noise_runs[r];
        const auto searched_rows = searched.middleRows(run.begin, run.rows);
        const Eigen::MatrixXd r_searched = noise::covariance_times(spectra[r], searched_rows);
        stack_searched += ident::cross_product(s.phi.middleRows(run.begin, run.rows), r_searched);
        searched_meat += ident::cross_product(searched_rows, r_searched);
      }
      const Eigen::MatrixXd terms_searched = terms_rows(stack_searched);
      coloured.meat.topRightCorner(p, q) = terms_searched;
      coloured.meat.bottomLeftCorner(q, p) = terms_searched.transpose();
      coloured.meat.bottomRightCorner(q, q) = 0.5 * (searched_meat + searched_meat.transpose());
    }
    coloured.cross = Eigen::MatrixXd::Zero(p + q, static_cast<Eigen::Index>(coloured.cluster_ids.size()));
    for (std::size_t r = 0; r < spectra.size(); ++r) {
      const CaseRows& run = h.layout->noise_runs[r];
      const Eigen::MatrixXd cross = noise::group_cross_covariance(spectra[r], run_phases[r], s.phi.middleRows(run.begin, run.rows),
                                                                  searched.middleRows(run.begin, run.rows));
      const Eigen::MatrixXd terms_cross = terms_rows(cross.topRows(s.phi.cols()));
      for (std::size_t a = 0; a < run_phase_columns[r].size(); ++a) {
        auto cluster = coloured.cross.col(run_phase_columns[r][a]);
        cluster.head(p) += terms_cross.col(Eigen::Index(a));
        cluster.tail(q) += cross.col(Eigen::Index(a)).tail(q);
      }
    }
    // The placements' part P P' of R (X'PP'X, X'PP'Z, Z'PP'Z), and what each placement leaves on
    // the clusters' means, the offsets' known part where they are weighed.
    coloured.sums_covariance = noise_sums_covariance;
    ident::ClusterSums cluster_sums = ident::ClusterSums::from_rows(s.phi, fit.residuals, h.layout->clusters, h.layout->loading);
    {
      const Eigen::MatrixXd searched_sums = ident::ClusterSums::from_rows(searched, fit.residuals, h.layout->clusters).columns;
      Eigen::MatrixXd columns_sums(p + q, cluster_sums.columns.cols());
      columns_sums << terms_rows(cluster_sums.columns), searched_sums;
      cluster_sums.columns = std::move(columns_sums);
    }
    Eigen::VectorXd placed_offset_variance;
    if (placed.cols() > 0) {
      Eigen::MatrixXd z_placed = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(coloured.cluster_ids.size()), placed.cols());
      for (Eigen::Index r = 0; r < placed.rows(); ++r) {
        const int id = h.layout->clusters[static_cast<std::size_t>(r)];
        z_placed.row(std::lower_bound(coloured.cluster_ids.begin(), coloured.cluster_ids.end(), id) - coloured.cluster_ids.begin()) +=
            placed.row(r);
      }
      Eigen::MatrixXd x_placed(p + q, placed.cols());
      x_placed << terms_rows(ident::cross_product(s.phi, placed)), ident::cross_product(searched, placed);
      coloured.meat.noalias() += x_placed * x_placed.transpose();
      coloured.cross.noalias() += x_placed * z_placed.transpose();
      coloured.sums_covariance.noalias() += z_placed * z_placed.transpose();
      coloured.stated_offsets = true;
      placed_offset_variance = z_placed.rowwise().squaredNorm().cwiseQuotient(cluster_sums.rows.cwiseAbs2());
    }
    // Nothing is estimated elsewhere from the phases' means: what was (angles, corner) is in X.
    out.offsets = ident::cluster_offsets(cluster_sums, ident::GramFactor::from_blocks(x_blocks), fit.residual_variance, 0, &coloured);
    if (stack_gram.size() == 0) stack_gram = ident::gram(s.phi);
    const Eigen::MatrixXd terms_gram = signs.asDiagonal() * stack_gram(stack_columns, stack_columns) * signs.asDiagonal();
    // Which terms live between the phases: little of their column varies within one.
    const std::vector<bool> phase_level = ident::phase_level_columns(cluster_sums, terms_gram.diagonal());
    // When the phases' means are all the model's columns say (every term constant within each
    // phase: static poses) and their offsets differ, each mean is weighed by what its offset
    // leaves of it (random effects). Where a column varies within the phases the weights would
    // also trade the means against that variation, which leans on the within-phase noise model,
    // and on sim-paper-daq the weighed estimates' sd understated their spread more than least
    // squares' did (plan-check; docs/validation.md, 'Evidence behind choices in the code'), so
    // there least squares with the sandwich above stays. So it does for ULS's output-multiplied
    // columns and noise terms, which carry their own noise model.
    std::optional<ident::RandomEffectsFit> weighed;
    const bool means_only = std::all_of(phase_level.begin(), phase_level.end(), [](bool b) { return b; });
    // A static case's placement is an offset of its cluster: the stated placements weigh the
    // clusters' means with the estimated offsets, and are R's in the weighed fit's covariance.
    const auto covariance_times = [&](const Eigen::MatrixXd& m) {
      Eigen::MatrixXd out = noise_times(m);
      if (placed.cols() > 0) out.noalias() += placed * (placed.transpose() * m);
      return out;
    };
    if (means_only && (out.offsets.tau2 > 0.0 || placed.cols() > 0) && output_multiplied.empty() && fit.theta.size() == p) {
      // The weighed fit reads X whole (static poses: a plan of few rows per parameter).
      Eigen::MatrixXd x(x_blocks.rows, x_blocks.cols);
      fill_x(0, x);
      weighed = ident::weighed_by_offsets(
          out.offsets, cluster_sums.loading, noise_sums_covariance.diagonal(),
          [&](const Eigen::VectorXd& tau2) {
            return ident::random_effects_fit(x, p, s.y, h.layout->clusters, tau2, noise_sums_covariance.diagonal(),
                                             covariance_times, placed_offset_variance);
          },
          placed_offset_variance);
    }
    if (weighed) {
      out.offsets.within = weighed->within;
      out.offsets.covariance = weighed->covariance;
      out.offsets.weights = weighed->weights;
    }
    // The searched parameters' rows and columns have done their work (the terms' block of the
    // joint covariance includes them); what is reported is the terms'.
    out.searched_covariance = out.offsets.covariance.bottomRightCorner(n_searched, n_searched);
    out.offsets.classical = fit.residual_variance * terms_gram.ldlt().solve(Eigen::MatrixXd::Identity(p, p));
    for (Eigen::MatrixXd* m : {&out.offsets.within, &out.offsets.covariance}) *m = m->topLeftCorner(p, p).eval();
    // The fit's covariance (ULS's, with its bias correction) takes the residual as white and the
    // searched parameters as known: what the residual's colour, the offsets between phases and
    // the searched parameters add to that is added to it.
    // The weighed estimate's covariance is its own sandwich, whole.
    Eigen::MatrixXd covariance = weighed ? out.offsets.covariance
                                         : Eigen::MatrixXd(fit.covariance.topLeftCorner(p, p) + out.offsets.covariance -
                                                           out.offsets.classical);
    if (h.held_covariance) {   // the least-squares fit's response to a held turn stands for the weighed one's
      out.held_covariance = h.held_covariance(fit);
      covariance += out.held_covariance;
    }
    if (weighed) {
      fit.theta.head(p) = weighed->theta;
      fit.residuals = s.y;
      for (Eigen::Index j = 0; j < p; ++j) fit.residuals -= (signs(j) * weighed->theta(j)) * s.phi.col(stack_columns[std::size_t(j)]);
      fit.residual_variance = fit.residuals.squaredNorm() / static_cast<double>(std::max<Eigen::Index>(1, fit.residuals.size() - p));
    }
    fit.covariance.topLeftCorner(p, p) = covariance;
    // A variance that rounding left at or below zero belongs to a column the joint design (with the
    // searched parameters' columns) cannot tell from the others: not determined, t 0, never a t of
    // infinity (on a tumble: sign(a_i) and a_i*abs(a_i) beside a_i).
    fit.std_dev = fit.covariance.diagonal().unaryExpr([](double v) {
      return v > 0.0 && std::isfinite(v) ? std::sqrt(v) : std::numeric_limits<double>::infinity();
    });
    // Each term's test and which term leaves: ident::term_leaving, the rule the live estimate
    // applies too. A tumble's bias and scale factor, from the two poses a placement tilt hardly
    // moves, are then known on the noise's dof; the angles, from the four it moves, on the poses'.
    std::vector<ident::TermTest> tests(static_cast<std::size_t>(p));
    for (Eigen::Index j = 0; j < p; ++j) {
      const std::string& label = fit.labels[std::size_t(j)];
      ident::TermTest& test = tests[std::size_t(j)];
      test.t = fit.theta(j) / fit.std_dev(j);
      test.samples_dof = out.dof(j);
      test.phase_level = phase_level[std::size_t(j)];
      test.removable = !(ident::never_pruned(label, h.sensor) || (h.protect && h.protect(label)));
      out.dof(j) = ident::term_test_dof(out.offsets, j, test);
    }
    const std::optional<ident::TermLeaving> leaves = ident::term_leaving(out.offsets, tests, h.threshold);
    const Eigen::Index worst = leaves ? static_cast<Eigen::Index>(leaves->term) : -1;
    if (worst < 0 || !h.may_remove) return finish();
    const std::string label = fit.labels[std::size_t(worst)];
    pruned.push_back({label, leaves->saturated, tests[std::size_t(worst)].t, leaves->dof, out.offsets.clusters,
                      static_cast<bool>(h.held_covariance)});
    const auto at = std::find(s.labels.begin(), s.labels.end(), label);
    std::erase(columns, static_cast<Eigen::Index>(at - s.labels.begin()));
    fit = fit_identifiable(s, h.sensor, columns, uls, dropped);
  }
}

}  // namespace inertia::procedure
