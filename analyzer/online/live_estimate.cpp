// The online estimator's estimate from its statistics (live_estimate.hpp).
#include "analyzer/online/live_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/stacked_regression.hpp"

namespace inertia::online {

using Eigen::Index;
using ident::Variable;

LiveEstimate EstimateSolver::solve(bool update_states, const std::optional<LeftOut>& left_out,
                                   const std::vector<Eigen::Matrix3d>* fixed_m_cs,
                                   const std::vector<Eigen::Matrix3d>* fixed_angle_covariances,
                                   const std::vector<std::array<bool, 3>>* fixed_held_angles,
                                   const LiveEstimate* fixed_from) {
  LiveEstimate s;
  s.infos.assign(statistics.mountings.size(), live.empty_information());
  // Each mounting's cases' placements (procedure/placement.hpp) beside their statistics.
  std::vector<std::vector<procedure::CasePlacement>> placements(statistics.mountings.size());
  for (std::size_t c = 0; c < statistics.cases.size(); ++c) {
    const std::optional<Information> info = statistics.case_information(c, left_out);
    if (!info) continue;
    const std::size_t m = statistics.cases[c].mounting;
    s.infos[m].add(*info);
    placements[m].push_back({info->input_gram(), statistics.cases[c].placement_sd_rad});
  }
  // The mounting rules' order (procedure/mounting_rules.hpp), as the batch takes them.
  {
    std::vector<procedure::MountingKind> kinds;
    for (const CaseAccumulator::MountingState& ms : statistics.mountings) kinds.push_back(ms.kind);
    s.order = procedure::mounting_order(kinds);
  }
  if (fixed_m_cs != nullptr) {
    s.m_cs = *fixed_m_cs;
    std::vector<const Information*> infos;
    for (const Information& i : s.infos) infos.push_back(&i);
    // The terms the full solution determined (what it dropped or could not determine stays out:
    // of three squares that sum to one with the bias, which one goes is rounding's choice) and
    // its count of phase-level parameters.
    const LiveSolver batch_solver = fixed_from != nullptr ? live.solver->with_model(fixed_from->batch.terms) : *live.solver;
    s.aligned = fixed_from == nullptr || fixed_from->aligned;
    s.model = batch_solver.model();
    s.batch = batch_solver.fit_batch(infos, s.m_cs);
    if (fixed_angle_covariances != nullptr && fixed_held_angles != nullptr)
      batch_solver.add_misalignment_uncertainty(s.batch, infos, s.m_cs, *fixed_angle_covariances, *fixed_held_angles);
    const CaseStatistics cs = case_statistics(s.m_cs, left_out);
    s.angles_from_means = angles_from_means(nullptr);
    add_case_scatter(s, cs, batch_solver);
    return s;
  }
  const LiveSolver active = active_solver(live.model);
  std::optional<double> bias;
  double bias_sd = 0.0;
  std::vector<MountingFit> fits(statistics.mountings.size());
  for (std::size_t m : s.order) {
    MountingStatistics d;
    d.name = statistics.mountings[m].name;
    d.info = s.infos[m];
    d.kind = statistics.mountings[m].kind;
    // Algorithm 1 starts where the batch starts it, every time: a start from an earlier, less
    // determined estimate (one orientation so far) can lead the fixed point elsewhere.
    d.m_cs = live.model_m_cs;
    d.hold_unexcited = hold_unexcited;
    d.placements = placements[m];
    const bool takes = procedure::takes_bias(d.kind, live.options.solver.ieee_1293);
    fits[m] = active.fit_mounting(d, takes ? bias : std::nullopt, takes ? bias_sd : 0.0);
    if (!bias && procedure::hands_on_bias(d.kind) && fits[m].bias) {
      bias = fits[m].bias;
      bias_sd = fits[m].bias_sd;
    }
  }
  // A mounting whose data does not fix its misalignment keeps the nominal frame (the batch's
  // rule: another mounting's M_C^S is another fixture's), within the mounting tolerance.
  std::optional<std::size_t> reference;
  for (std::size_t m : s.order)
    if (fits[m].determined && !reference) reference = m;
  // With none aligned, the sensor frame's p and o axes are not known in any case: only the
  // terms that hold in any frame near it are fitted (procedure::frame_free), as in the batch.
  const LiveSolver batch_solver = reference ? active : active_solver(live.frame_free_model);
  std::vector<const Information*> infos;
  std::vector<Eigen::Matrix3d> m_cs;
  for (std::size_t m = 0; m < statistics.mountings.size(); ++m) {
    infos.push_back(&s.infos[m]);
    m_cs.push_back(fits[m].m_cs);
    if (update_states) {
      if (fits[m].determined) statistics.mountings[m].m_cs = fits[m].m_cs;
      statistics.mountings[m].fit = fits[m];
    }
  }
  s.batch = batch_solver.fit_batch(infos, m_cs);
  // Each case's statistics, which the turns' and the terms' inference read by clusters.
  CaseStatistics cs = case_statistics(m_cs, left_out);
  // The twists about n_i against the reference, as the batch pipeline finds them (at the corner
  // found first, which the pipeline keeps).
  std::vector<RelativeTurn> turns(statistics.mountings.size());
  if (reference && s.batch.ok) {
    std::vector<bool> aligned(fits.size());
    std::vector<std::array<bool, 2>> tilts_determined(fits.size());
    for (std::size_t m = 0; m < fits.size(); ++m) {
      aligned[m] = fits[m].determined;
      for (int axis = 0; axis < 2; ++axis)
        tilts_determined[m][static_cast<std::size_t>(axis)] = !fits[m].held[static_cast<std::size_t>(procedure::angle_of_turn(axis))];
    }
    // The turns' covariance by the clusters' rule the coefficients get (add_case_scatter).
    CaseClusters clusters;
    clusters.infos = cs.infos;
    for (const std::size_t c : cs.state) clusters.mountings.push_back(statistics.cases[c].mounting);
    clusters.run_noise = run_noise(cs);
    clusters.noise_gain = 1.0 - noise.ar.sum();
    clusters.angles_from_means = angles_from_means(&fits);
    turns = active.relative_turns(infos, m_cs, *reference, aligned, tilts_determined, s.batch.corner_rad_s, &clusters);
    if (std::any_of(turns.begin(), turns.end(), [](const RelativeTurn& t) { return t.estimated; }))
      s.batch = active.fit_batch_at(infos, m_cs, s.batch.corner_rad_s);
  }
  std::vector<Eigen::Matrix3d> angle_covariances;
  std::vector<std::array<bool, 3>> held_angles;
  for (std::size_t m = 0; m < statistics.mountings.size(); ++m) {
    Eigen::Matrix3d c = fits[m].angles_covariance;   // a held angle: the tolerance
    std::array<bool, 3> held = fits[m].held;
    if (turns[m].estimated) {
      // The turn's information is the noise's; the cases' placements move its tilts as they moved
      // the mounting's.
      c = turns[m].covariance + fits[m].placement_angles_covariance;
      // The tilts as algorithm 1 reads them (of n_i alone); about i the twist found.
      MountingFit& f = fits[m];
      f.m_cs = m_cs[m];
      f.angles = procedure::rotation_vector(
          procedure::misalignment_from_sensitivities(m_cs[m].row(0).transpose(), frames::Dcm::Identity()));
      f.angles(0) = turns[m].twist_rad;
      f.angles_covariance = c;
      f.angles_sd = c.diagonal().cwiseMax(0.0).cwiseSqrt();
      f.held = turns[m].held_angles;
      held = f.held;
      if (update_states) {
        statistics.mountings[m].m_cs = f.m_cs;
        statistics.mountings[m].fit = f;
      }
    }
    if (turns[m].held) {
      c += turns[m].covariance;
      held[0] = true;
      const std::string why = procedure::held_twist_note(statistics.mountings[m].name, statistics.mountings[*reference].name,
                                                         turns[m].why, live.options.solver.mounting_tolerance_rad);
      for (MountingFit* f : {&fits[m], update_states ? &statistics.mountings[m].fit : nullptr})
        if (f != nullptr) f->note += (f->note.empty() ? "" : "; ") + why;
    }
    angle_covariances.push_back(c);
    held_angles.push_back(held);
  }
  // A searched model's structure by algorithm 2 (section 2.7.2), as the batch selects its own
  // before the inference. The terms the fit did not determine stay in the model, named as such.
  std::optional<LiveSolver> selected(batch_solver);   // holds its basis by reference: emplaced, not assigned
  const std::size_t search_space = s.batch.terms.size();
  if (live.searched && s.batch.ok) {
    const std::vector<Index> chosen = batch_solver.select(s.batch, infos, m_cs);
    std::vector<Index> model = batch_solver.model();
    for (const Index t : s.batch.terms) {
      if (std::find(chosen.begin(), chosen.end(), t) != chosen.end()) continue;
      s.insignificant.push_back(t);
      std::erase(model, t);
    }
    if (!s.insignificant.empty()) {
      selected.emplace(batch_solver.with_model(std::move(model)));
      s.batch = selected->fit_batch_at(infos, m_cs, s.batch.corner_rad_s);
    }
  }
  for (std::size_t k = 0; k < cs.state.size(); ++k) cs.m_cs[k] = m_cs[statistics.cases[cs.state[k]].mounting];   // as turned
  const LiveSolver fitted = infer_and_prune(s, *selected, search_space, infos, m_cs, cs, fits, angle_covariances, held_angles);
  s.model = fitted.model();
  s.aligned = reference.has_value();
  s.m_cs = std::move(m_cs);
  s.angle_covariances = std::move(angle_covariances);
  s.held_angles = std::move(held_angles);
  return s;
}

LiveSolver EstimateSolver::active_solver(const std::vector<Index>& terms) const {
  // The batch's rules on its candidates: temperature terms once the temperature moved, and a
  // searched model's products of inputs once the plan's own inputs excite them (plan_validation.hpp).
  std::vector<Index> kept;
  for (Index t : terms) {
    if (!statistics.temperature_moved() && live.basis->terms()[static_cast<std::size_t>(t)].uses(Variable::T)) continue;
    if (live.searched && !statistics.excited(t)) continue;
    kept.push_back(t);
  }
  return live.solver->with_model(std::move(kept));
}

EstimateSolver::CaseStatistics EstimateSolver::case_statistics(const std::vector<Eigen::Matrix3d>& m_cs,
                                                               const std::optional<LeftOut>& left_out) const {
  CaseStatistics out;
  out.with_open.reserve(statistics.cases.size());
  for (std::size_t c = 0; c < statistics.cases.size(); ++c) {
    std::optional<Information> info = statistics.case_information(c, left_out);
    if (!info) continue;
    out.with_open.push_back(std::move(*info));
    out.m_cs.push_back(m_cs[statistics.cases[c].mounting]);
    out.state.push_back(c);
  }
  for (const Information& i : out.with_open) out.infos.push_back(&i);
  return out;
}

int EstimateSolver::angles_from_means(const std::vector<MountingFit>* fits) const {
  int n = 0;
  for (std::size_t m = 0; m < statistics.mountings.size(); ++m) {
    const bool determined = fits != nullptr ? (*fits)[m].determined : statistics.mountings[m].fit.determined;
    if (statistics.mountings[m].poses_only && determined) n += 2;
  }
  return n;
}

std::vector<Eigen::MatrixXd> EstimateSolver::run_noise(const CaseStatistics& cs) {
  std::vector<Eigen::MatrixXd> out(cs.infos.size());
  run_noise_.resize(statistics.cases.size());
  for (std::size_t k = 0; k < cs.infos.size(); ++k) {
    const std::function<double(double)>& density = noise.density_of(cs.state[k]);
    if (!density) continue;
    const Information& info = *cs.infos[k];
    std::vector<std::int64_t> rows(info.runs());
    for (std::size_t r = 0; r < rows.size(); ++r) rows[r] = info.run_samples(r);
    RunNoise& cached = run_noise_[cs.state[k]];
    if (cached.rows != rows) {
      // The case's runs one after the other (a case's phases, in the order they ran).
      noise::RowGroups groups;
      groups.groups = static_cast<Index>(rows.size());
      for (std::size_t r = 0; r < rows.size(); ++r) groups.group.insert(groups.group.end(), static_cast<std::size_t>(rows[r]), static_cast<Index>(r));
      cached.sums_covariance = groups.group.empty() ? Eigen::MatrixXd::Zero(groups.groups, groups.groups)
                                                    : noise::group_covariance(noise::spectrum_of(static_cast<Index>(groups.group.size()), density), groups);
      cached.rows = std::move(rows);
    }
    out[k] = cached.sums_covariance;
  }
  return out;
}

void EstimateSolver::add_case_scatter(LiveEstimate& s, const CaseStatistics& cs, const LiveSolver& batch_solver) {
  const std::vector<Eigen::MatrixXd> coloured = run_noise(cs);
  s.scatter = batch_solver.add_case_scatter(s.batch, cs.infos, cs.m_cs, 1.0 - noise.ar.sum(), s.angles_from_means, &coloured);
}

LiveSolver EstimateSolver::infer_and_prune(LiveEstimate& s, const LiveSolver& batch_solver, std::size_t search_space,
                                           const std::vector<const Information*>& infos,
                                           const std::vector<Eigen::Matrix3d>& m_cs, const CaseStatistics& cs,
                                           const std::vector<MountingFit>& fits,
                                           const std::vector<Eigen::Matrix3d>& angle_covariances,
                                           const std::vector<std::array<bool, 3>>& held_angles) {
  std::optional<LiveSolver> current(batch_solver);   // LiveSolver holds its basis by reference: emplaced, not assigned
  const auto never_pruned = [&](Index t) {
    return ident::never_pruned(live.basis->terms()[static_cast<std::size_t>(t)].to_string(), live.sensor);
  };
  s.angles_from_means = angles_from_means(&fits);
  const double threshold = ident::family_threshold(live.options.solver.structure_alpha, search_space);
  for (;;) {
    if (!s.batch.ok) return *current;
    current->add_misalignment_uncertainty(s.batch, infos, m_cs, angle_covariances, held_angles);
    add_case_scatter(s, cs, *current);
    const std::vector<Index>& level = s.scatter.phase_level;
    std::vector<ident::TermTest> tests(s.batch.terms.size());
    for (std::size_t k = 0; k < s.batch.terms.size(); ++k) {
      const Index t = s.batch.terms[k];
      ident::TermTest& test = tests[k];
      test.t = s.batch.theta(static_cast<Index>(k)) / s.batch.sd(static_cast<Index>(k));
      test.samples_dof = s.batch.weight - static_cast<double>(s.batch.terms.size());
      test.phase_level = std::find(level.begin(), level.end(), t) != level.end();
      test.removable = !never_pruned(t) && (test.phase_level || live.searched);
    }
    const std::optional<ident::TermLeaving> leaving = ident::term_leaving(s.scatter.offsets, tests, threshold);
    if (!leaving) return *current;
    const Index weakest = s.batch.terms[leaving->term];
    (tests[leaving->term].phase_level ? s.confounded : s.insignificant).push_back(weakest);
    std::vector<Index> kept = current->model();
    std::erase(kept, weakest);
    current.emplace(current->with_model(std::move(kept)));
    s.batch = current->fit_batch_at(infos, m_cs, s.batch.corner_rad_s);
  }
}

}  // namespace inertia::online
