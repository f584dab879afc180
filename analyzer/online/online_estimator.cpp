// OnlineEstimator (online_estimator.hpp): the model it fits (live_model.hpp), the statistics of
// the rows per case and mounting (case_accumulator.hpp), the noise model fitted on the first rows
// (live_noise_model.hpp), the estimate solved from the statistics (live_estimate.hpp) and its
// convergence test (convergence_test.hpp), composed; here the rows come in and the snapshot, the
// estimate as model_estimate_t publishes it, goes out.
#include "analyzer/online/online_estimator.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/online/case_accumulator.hpp"
#include "analyzer/online/convergence_test.hpp"
#include "analyzer/online/live_estimate.hpp"
#include "analyzer/online/live_model.hpp"
#include "analyzer/online/live_noise_model.hpp"
#include "analyzer/procedure/stacked_regression.hpp"

namespace inertia::online {

using Eigen::Index;
using ident::Term;

struct OnlineEstimator::Impl {
  Impl(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model, double t_ref, const OnlineOptions& options)
      : live(sensor, model, t_ref, options), statistics(live, noise), estimates(live, statistics, noise) {}

  LiveModel live;
  LiveNoiseModel noise;
  CaseAccumulator statistics;
  EstimateSolver estimates;
  ConvergenceTest convergence;

  void push(const fusion::FusedChunk& chunk, const config::TestCase& tc) {
    if (!statistics.push(chunk, tc)) return;
    if (!noise.fitted && static_cast<double>(noise.buffered_rows) * chunk.sample_period_s >= live.options.noise_window_s)
      noise.fit(live, statistics, estimates);
  }

  void end_of_stream() {
    if (!noise.fitted && noise.buffered_rows > 0) noise.fit(live, statistics, estimates);
  }

  OnlineSnapshot snapshot() {
    OnlineSnapshot out;
    for (const Term& t : live.model_terms) out.terms.push_back(t.to_string());
    const auto p = static_cast<Index>(live.model_terms.size());
    out.values = Eigen::VectorXd::Constant(p, kNaN);
    out.std_devs = Eigen::VectorXd::Constant(p, kNaN);
    out.t = Eigen::VectorXd::Constant(p, kNaN);
    out.noise_model_fitted = noise.fitted;
    out.noise_order = static_cast<int>(noise.ar.size());
    out.long_run_variance_factor = live.solver->long_run_variance_factor();
    LiveEstimate s = estimates.solve(true);
    std::int64_t samples = 0;
    for (const Information& i : s.infos) samples += i.samples();
    out.samples_used = samples;
    out.cases_used = static_cast<std::int64_t>(statistics.cases_with_data());
    for (std::size_t m = 0; m < statistics.mountings.size(); ++m) {
      const CaseAccumulator::MountingState& ms = statistics.mountings[m];
      MountingEstimate e;
      e.name = ms.name;
      for (std::size_t c : ms.cases) e.cases.push_back(statistics.cases[c].name);
      e.determined = ms.fit.determined;
      e.m_cs = ms.fit.m_cs;
      e.angles_rad = ms.fit.angles;
      e.angles_sd_rad = ms.fit.angles_sd;
      e.samples = s.infos[m].samples();
      e.note = ms.fit.note;
      out.mountings.push_back(std::move(e));
    }
    if (!s.batch.ok) {
      for (const Term& t : live.model_terms) out.undetermined.push_back(t.to_string());
      out.convergence = s.batch.why.empty() ? "no estimate yet" : s.batch.why;
      return out;
    }
    for (std::size_t j = 0; j < live.model.size(); ++j) {
      bool found = false;
      for (std::size_t k = 0; k < s.batch.terms.size(); ++k) {
        if (s.batch.terms[k] != live.model[j]) continue;
        out.values(static_cast<Index>(j)) = s.batch.theta(static_cast<Index>(k));
        out.std_devs(static_cast<Index>(j)) = s.batch.sd(static_cast<Index>(k));
        out.t(static_cast<Index>(j)) = s.batch.theta(static_cast<Index>(k)) / s.batch.sd(static_cast<Index>(k));
        found = true;
      }
      if (found) continue;
      out.undetermined.push_back(live.model_terms[j].to_string());
      if (std::find(s.confounded.begin(), s.confounded.end(), live.model[j]) != s.confounded.end())
        out.confounded.push_back(live.model_terms[j].to_string());
      else if (std::find(s.insignificant.begin(), s.insignificant.end(), live.model[j]) != s.insignificant.end())
        out.insignificant.push_back(live.model_terms[j].to_string());
      else if ((!s.aligned && !procedure::frame_free(live.model_terms[j])) || statistics.whole_plan_in())
        out.plan_undetermined.push_back(live.model_terms[j].to_string());
    }
    out.residual_variance = s.batch.s2;
    out.corner_rad_s = s.batch.corner_rad_s;
    if (live.options.structure_table) {
      std::vector<const Information*> infos;
      std::vector<Eigen::Matrix3d> m_cs;
      for (std::size_t m = 0; m < statistics.mountings.size(); ++m) {
        infos.push_back(&s.infos[m]);
        m_cs.push_back(statistics.mountings[m].fit.determined ? statistics.mountings[m].fit.m_cs : statistics.mountings[m].m_cs);
      }
      for (const CandidateStat& c : live.solver->with_model(s.model).structure(live.candidates, s.batch, infos, m_cs)) {
        const Term& t = live.basis->terms()[static_cast<std::size_t>(c.term)];
        out.structure.push_back({t.to_string(), ident::physical_name(t, live.sensor), c.err, c.value, c.sd, c.t, c.significant});
      }
      std::stable_sort(out.structure.begin(), out.structure.end(),
                       [](const CandidateEstimate& a, const CandidateEstimate& b) { return a.err > b.err; });
    }
    convergence.update(s, out, live, statistics, estimates);
    out.converged = convergence.converged;
    out.convergence = convergence.convergence;
    return out;
  }
};

std::vector<Term> OnlineEstimator::default_terms(dataset::SensorKind sensor, bool temperature) {
  return LiveModel::default_terms(sensor, temperature);
}

OnlineEstimator::OnlineEstimator(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model, double t_ref,
                                 const OnlineOptions& options)
    : impl_(std::make_unique<Impl>(sensor, model, t_ref, options)) {
  // No noise window, or no order to fit: white noise from the first row on.
  impl_->noise.fitted = options.noise_window_s <= 0.0 || options.whitening_max_order <= 0;
}

OnlineEstimator::~OnlineEstimator() = default;

void OnlineEstimator::push(const fusion::FusedChunk& chunk, const config::TestCase& tc) { impl_->push(chunk, tc); }
void OnlineEstimator::end_segment(const fusion::SegmentEnd& end) { impl_->statistics.end_segment(end); }
void OnlineEstimator::end_of_stream() { impl_->end_of_stream(); }
OnlineSnapshot OnlineEstimator::snapshot() { return impl_->snapshot(); }
std::int64_t OnlineEstimator::rows_pushed() const { return impl_->statistics.rows_total; }
std::vector<std::string> OnlineEstimator::terms() const { return ident::to_strings(impl_->live.model_terms); }

}  // namespace inertia::online
