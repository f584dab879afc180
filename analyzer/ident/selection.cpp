#include "analyzer/ident/selection.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <stdexcept>

namespace inertia::ident {
namespace {

// One regression problem as the selection reads it: the fits of column subsets, the t-test's
// theta and sd, the scores of steps 11-12 and the ERR Gram matrix. Two sources: the rows
// (RowsContext; offline) and the normal equations alone (EquationsContext; the live estimator).
class FitContext {
 public:
  FitContext(const std::vector<std::string>& labels, const UlsOptions& options) : labels_(labels), options_(options) {}
  FitContext(const FitContext&) = delete;
  FitContext& operator=(const FitContext&) = delete;
  virtual ~FitContext() = default;

  /// Step 10: the fit of `columns` with its final covariance.
  [[nodiscard]] virtual UlsResult fit(const std::vector<Index>& columns) const = 0;
  /// Step 5: the fit of `columns`, its coefficients alone where they need no data pass.
  [[nodiscard]] virtual UlsResult coefficients(const std::vector<Index>& columns) const { return fit(columns); }
  /// theta and sd for the t-test of step 9.
  [[nodiscard]] virtual std::pair<Eigen::VectorXd, Eigen::VectorXd> theta_sd(const std::vector<Index>& columns) const = 0;
  /// Steps 11-12 of the fit of `columns`: the residual mean test and AIC (eq. 9).
  virtual void score(const UlsResult& fit, const std::vector<Index>& columns, CandidateModel& model) const = 0;
  /// The ERR Gram matrix [Phi y]'[Phi y] (ERR does not depend on column scale or sign).
  [[nodiscard]] virtual Eigen::MatrixXd err_gram() const = 0;
  [[nodiscard]] virtual Index samples() const = 0;

  [[nodiscard]] Index terms() const { return static_cast<Index>(labels_.size()); }
  [[nodiscard]] const std::vector<std::string>& labels() const { return labels_; }

 protected:
  [[nodiscard]] bool has_output_multiplied(const std::vector<Index>& columns) const {
    return std::any_of(columns.begin(), columns.end(), [this](Index c) {
      return std::find(stats_.denominator.begin(), stats_.denominator.end(), c) != stats_.denominator.end();
    });
  }
  /// ULS on the statistics of `columns` (O(p^3), no data pass).
  [[nodiscard]] UlsSolution solve(const std::vector<Index>& columns) const {
    std::vector<std::string> names;
    names.reserve(columns.size());
    for (Index c : columns) names.push_back(labels_[static_cast<std::size_t>(c)]);
    return solve_uls(stats_.subset(columns), names, options_);
  }
  /// The classical sd of a solution: sum zeta^2 / (N - p) times (Phi'Phi)^-1, or the corrected
  /// inverse (Phi'Phi - sigma^2 Psi)^-1 with output-multiplied columns.
  [[nodiscard]] Eigen::VectorXd solution_sd(const UlsSolution& sol, Index columns, bool output_multiplied) const {
    const double dof = static_cast<double>(std::max<Index>(samples() - columns, 1));
    const Eigen::MatrixXd& inverse = output_multiplied ? sol.corrected_inverse : sol.gram_inverse;
    return (sol.zeta_energy / dof * inverse.diagonal().cwiseMax(0.0)).cwiseSqrt();
  }
  [[nodiscard]] Eigen::MatrixXd augmented_from_statistics() const {
    const Index p = stats_.terms();
    Eigen::MatrixXd g(p + 1, p + 1);
    g.topLeftCorner(p, p) = stats_.gram;
    g.col(p).head(p) = stats_.cross;
    g.row(p).head(p) = stats_.cross.transpose();
    g(p, p) = stats_.yy;
    return g;
  }

  const std::vector<std::string>& labels_;
  const UlsOptions& options_;
  UlsStatistics stats_;
};

class RowsContext final : public FitContext {
 public:
  RowsContext(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
              const std::vector<std::string>& labels, const OutputMultiplied& rational, std::span<const Index> stretch_starts,
              const UlsOptions& options)
      : FitContext(labels, options), phi_(phi), y_(y), rational_(rational), stretch_starts_(stretch_starts) {
    if (static_cast<Index>(labels.size()) != phi.cols())
      throw std::invalid_argument("selection: " + std::to_string(labels.size()) + " labels for " +
                                  std::to_string(phi.cols()) + " columns");
    if (y.size() != phi.rows()) throw std::invalid_argument("selection: y and Phi differ in length");
    factors_ = denominator_factors(phi, y, rational, labels);
    if (options.noise_lags == 0) stats_ = UlsStatistics::from_data(phi, y, rational.columns, factors_);
  }

  UlsResult fit(const std::vector<Index>& columns) const override {
    if (options_.noise_lags > 0) return uls_batch(phi_, y_, labels_, rational_, options_, columns);
    return finish_uls(phi_, y_, labels_, columns, rational_, factors_, solve(columns), options_);
  }

  // Without noise lags theta comes from the statistics; the residuals and the covariance would
  // cost a pass over the rows.
  UlsResult coefficients(const std::vector<Index>& columns) const override {
    if (options_.noise_lags > 0) return fit(columns);
    return solved_terms(solve(columns), labels_, columns);
  }

  // Polynomial fits without noise lags come from the statistics alone: pruning j terms one at a
  // time would otherwise cost O(N j^2) per candidate model. Rational or ELS fits need the data
  // (sandwich, residuals).
  std::pair<Eigen::VectorXd, Eigen::VectorXd> theta_sd(const std::vector<Index>& columns) const override {
    if (options_.noise_lags > 0 || has_output_multiplied(columns)) {
      const UlsResult r = fit(columns);
      return {r.process_theta(), r.std_dev.head(r.process_terms)};
    }
    const UlsSolution sol = solve(columns);
    return {sol.theta, solution_sd(sol, static_cast<Index>(columns.size()), false)};
  }

  void score(const UlsResult& fit, const std::vector<Index>&, CandidateModel& model) const override {
    model.residual_mean = residual_mean_test(fit.residuals, stretch_starts_);      // step 12
    model.aic = aic(fit.residuals, static_cast<Index>(fit.theta.size()));           // step 11
  }

  // From the statistics when they exist, so the ranking costs no second data pass.
  Eigen::MatrixXd err_gram() const override {
    if (options_.noise_lags > 0) return ErrGram::from_data(phi_, y_).matrix();
    return augmented_from_statistics();
  }

  Index samples() const override { return phi_.rows(); }

 private:
  Eigen::Ref<const Eigen::MatrixXd> phi_;
  Eigen::Ref<const Eigen::VectorXd> y_;
  const OutputMultiplied& rational_;
  std::span<const Index> stretch_starts_;
  Eigen::MatrixXd factors_;
};

// A stage's normal equations and its residuals from elsewhere (StageProblem::equations): the fits,
// tests and scores of RowsContext without noise lags or output-multiplied columns, the same
// numbers to rounding, from the statistics and one residual pass per fit instead of its rows.
class SumsContext final : public FitContext {
 public:
  SumsContext(const NormalEquations& equations, const std::function<Eigen::VectorXd(std::span<const Index>, const Eigen::VectorXd&)>& residuals,
              std::span<const Index> stretch_starts, const UlsOptions& options)
      : FitContext(equations.labels(), options), equations_(equations), residuals_(residuals), stretch_starts_(stretch_starts) {
    if (options.noise_lags > 0 || !equations.output_multiplied().empty())
      throw std::invalid_argument("selection: a stage given by its sums is fitted by linear least squares alone");
    if (!residuals) throw std::invalid_argument("selection: a stage given by its sums needs its residuals");
    std::vector<Index> all(static_cast<std::size_t>(equations.columns()));
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<Index>(i);
    stats_ = equations.statistics(all);
  }

  // As finish_uls for a classical fit: the residual's energy over N - p times (Phi'Phi)^-1.
  UlsResult fit(const std::vector<Index>& columns) const override {
    const UlsSolution sol = solve(columns);
    UlsResult out = solved_terms(sol, labels_, columns);
    out.residuals = residuals_(columns, sol.theta);
    if (out.residuals.size() != samples()) throw std::logic_error("selection: the stage's residuals are not its rows");
    const double dof = static_cast<double>(std::max<Index>(samples() - static_cast<Index>(columns.size()), 1));
    out.residual_variance = out.residuals.squaredNorm() / dof;
    out.covariance_kind = CovarianceKind::Classical;
    out.covariance = out.residual_variance * sol.gram_inverse;
    out.std_dev = out.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    return out;
  }

  UlsResult coefficients(const std::vector<Index>& columns) const override { return solved_terms(solve(columns), labels_, columns); }

  std::pair<Eigen::VectorXd, Eigen::VectorXd> theta_sd(const std::vector<Index>& columns) const override {
    const UlsSolution sol = solve(columns);
    return {sol.theta, solution_sd(sol, static_cast<Index>(columns.size()), false)};
  }

  void score(const UlsResult& fit, const std::vector<Index>&, CandidateModel& model) const override {
    model.residual_mean = residual_mean_test(fit.residuals, stretch_starts_);      // step 12
    model.aic = aic(fit.residuals, static_cast<Index>(fit.theta.size()));           // step 11
  }

  Eigen::MatrixXd err_gram() const override { return augmented_from_statistics(); }
  Index samples() const override { return equations_.samples(); }

 private:
  const NormalEquations& equations_;
  const std::function<Eigen::VectorXd(std::span<const Index>, const Eigen::VectorXd&)>& residuals_;
  std::span<const Index> stretch_starts_;
};

// The normal equations alone: every fit, test and score from the statistics, no residuals.
//  - The output-multiplied columns' covariance is the classical one of the corrected inverse
//    (the sandwich needs the rows).
//  - AIC takes the residual energy from the statistics (yy - 2 theta'r + theta'R theta): exact
//    to about log10(y'y / sum zeta^2) fewer digits than from the residuals, ample for the
//    differences AIC compares at bench noise.
//  - Step 12 reads the residual's sum through the bias candidate's column (constant: "1", or "1"
//    through the noise model's A(q), whose gain is A(1)), whether the model holds it or not, and
//    its successive differences' energy from the differenced rows' Gram matrix
//    (NormalEquations::difference_augmented), so N_eff is the rows' (statistics.hpp). With no
//    bias among the candidates the mean is not known: not tested (p_res = 1, mean NaN).
class EquationsContext final : public FitContext {
 public:
  EquationsContext(const NormalEquations& equations, const UlsOptions& options)
      : FitContext(equations.labels(), options), equations_(equations) {
    if (options.noise_lags > 0)
      throw std::invalid_argument("selection: noise lags need the residuals; the normal equations alone have none");
    std::vector<Index> all(static_cast<std::size_t>(equations.columns()));
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<Index>(i);
    stats_ = equations.statistics(all);
    const auto bias = std::find(labels_.begin(), labels_.end(), "1");
    if (bias != labels_.end()) bias_ = static_cast<Index>(bias - labels_.begin());
  }

  UlsResult fit(const std::vector<Index>& columns) const override {
    const UlsSolution sol = solve(columns);
    const bool output_multiplied = has_output_multiplied(columns);
    const Index p = static_cast<Index>(columns.size());
    UlsResult out = solved_terms(sol, labels_, columns);
    out.residual_variance = sol.zeta_energy / static_cast<double>(std::max<Index>(samples() - p, 1));
    out.covariance = out.residual_variance * (output_multiplied ? sol.corrected_inverse : sol.gram_inverse);
    out.std_dev = out.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    out.covariance_kind = CovarianceKind::Classical;
    return out;
  }

  std::pair<Eigen::VectorXd, Eigen::VectorXd> theta_sd(const std::vector<Index>& columns) const override {
    const UlsSolution sol = solve(columns);
    return {sol.theta, solution_sd(sol, static_cast<Index>(columns.size()), has_output_multiplied(columns))};
  }

  void score(const UlsResult& fit, const std::vector<Index>& columns, CandidateModel& model) const override {
    const Index n = samples();
    const double energy = fit.residual_variance * static_cast<double>(std::max<Index>(n - fit.process_terms, 1));
    model.aic = aic_from_variance(energy / static_cast<double>(n), n, static_cast<Index>(fit.theta.size()));
    const Eigen::MatrixXd& a = equations_.augmented();
    const Index y = a.rows() - 1;
    if (bias_ < 0 || !(a(bias_, bias_) > 0.0)) {
      model.residual_mean = ResidualMeanTest();
      model.residual_mean.mean = std::numeric_limits<double>::quiet_NaN();
      model.residual_mean.effective_samples = static_cast<double>(n);
      return;
    }
    // bias' zeta = bias'y - sum_j sign_j theta_j bias'phi_j (ULS's linear form, uls_batch.hpp).
    const Eigen::VectorXd signs = linear_form_signs(equations_.columns(), equations_.output_multiplied());
    double product = a(bias_, y);
    for (std::size_t j = 0; j < columns.size(); ++j)
      product -= signs(columns[j]) * fit.theta(static_cast<Index>(j)) * a(bias_, columns[j]);
    const double level = std::sqrt(a(bias_, bias_) / static_cast<double>(n));
    const double mean = product / (level * static_cast<double>(n));
    // The residual's differences are the differenced rows' [dPhi dy] v, v = [-sign_j theta_j; 1].
    double differences = 0.0;
    const Index pairs = equations_.difference_pairs();
    if (pairs > 0) {
      std::vector<Index> at(columns.begin(), columns.end());
      at.push_back(y);
      Eigen::VectorXd v(static_cast<Index>(at.size()));
      for (std::size_t j = 0; j < columns.size(); ++j) v(static_cast<Index>(j)) = -signs(columns[j]) * fit.theta(static_cast<Index>(j));
      v(v.size() - 1) = 1.0;
      differences = v.dot(equations_.difference_augmented()(at, at) * v);
    }
    model.residual_mean = residual_mean_test(mean, energy - static_cast<double>(n) * mean * mean, n, differences, pairs);
  }

  Eigen::MatrixXd err_gram() const override { return augmented_from_statistics(); }
  Index samples() const override { return equations_.samples(); }

 private:
  const NormalEquations& equations_;
  Index bias_ = -1;
};

// Step 9 (and the refits of step 10 inside it): the columns that survive the t-test.
std::vector<Index> prune(const FitContext& context, std::vector<Index> columns,
                         const SelectionOptions& options, double threshold, CandidateModel& model,
                         const std::vector<Index>& kept = {}) {
  for (;;) {
    const auto [theta, sd] = context.theta_sd(columns);
    const ParameterTTest tt = parameter_t_test(theta, sd, context.samples());
    std::vector<double> p_value(tt.p_value.data(), tt.p_value.data() + tt.p_value.size());
    for (std::size_t i = 0; i < p_value.size(); ++i) {
      if (std::find(kept.begin(), kept.end(), columns[i]) != kept.end()) p_value[i] = std::numeric_limits<double>::quiet_NaN();
    }
    const std::optional<std::size_t> worst = term_to_prune(p_value, threshold);   // NaN p-values (dof <= 0) never leave
    if (!worst) break;
    std::vector<Index> keep;
    for (std::size_t i = 0; i < p_value.size(); ++i) {
      const bool drop = options.one_at_a_time ? i == *worst : p_value[i] > threshold;
      if (drop) {
        model.removed.push_back(context.labels()[static_cast<std::size_t>(columns[i])]);
      } else {
        keep.push_back(columns[i]);
      }
    }
    columns = std::move(keep);
  }
  return columns;
}

// Steps 10-12 on the surviving columns.
void score(const FitContext& context, const std::vector<Index>& columns, CandidateModel& model) {
  UlsResult fit = context.fit(columns);  // with the final covariance (and the residuals, from rows)
  model.t_test = parameter_t_test(fit.process_theta(), fit.std_dev.head(fit.process_terms),
                                  context.samples());
  model.columns = columns;
  context.score(fit, columns, model);
  model.fit = std::move(fit);
  model.ok = true;
}

// log of fitness up to the common factor exp(AIC_min / 2): ranks models before AIC_min is known.
double log_score(const CandidateModel& m) {
  return (m.residual_mean.p_value > 0.0 ? std::log(m.residual_mean.p_value)
                                        : -std::numeric_limits<double>::infinity()) -
         m.aic / 2.0;
}

}  // namespace

bool SelectionOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& s) {
    if (why != nullptr) *why = s;
    return false;
  };
  if (!(alpha > 0.0 && alpha < 1.0)) return fail("alpha = " + std::to_string(alpha) + " is outside (0, 1)");
  if (max_terms == 0 || max_terms < -1) return fail("max_terms must be -1 or >= 1");
  return uls.is_valid(why);
}

namespace {

// Algorithm 2 on `base`, whatever its source.
SelectionResult select_on(const FitContext& base, std::vector<Index> ranking, const std::vector<Index>& kept_columns,
                          std::span<const Index> stretch_starts, const SelectionOptions& options, FitHook* hook) {
  SelectionResult out;
  out.ranking = std::move(ranking);
  if (out.ranking.empty()) out.ranking = err_rank(base.err_gram(), options.err).order;
  for (Index c : out.ranking)
    if (c < 0 || c >= base.terms()) throw std::invalid_argument("selection: ranking index out of range");
  const std::size_t count =
      options.max_terms < 0 ? out.ranking.size()
                            : std::min(out.ranking.size(), static_cast<std::size_t>(options.max_terms));

  const double threshold =
      options.multiplicity == Multiplicity::Bonferroni ? family_threshold(options.alpha, out.ranking.size()) : options.alpha;
  StageProblem stage;
  Index scored_samples = -1;
  std::ptrdiff_t best = -1;
  std::map<std::vector<Index>, std::size_t> scored;  // term set -> first candidate with it
  for (std::size_t j = 1; j <= count; ++j) {
    CandidateModel model;
    model.ranked_terms = j;
    try {
      const std::vector<Index> ranked(out.ranking.begin(), out.ranking.begin() + static_cast<std::ptrdiff_t>(j));
      if (hook != nullptr) {
        const UlsResult ranked_fit = base.coefficients(ranked);  // step 5
        model.transformed = hook->transform(j, ranked_fit, stage);
      }
      if (model.transformed) {
        std::unique_ptr<FitContext> stage_context;
        if (stage.equations) {
          stage_context = std::make_unique<SumsContext>(*stage.equations, stage.residuals, stretch_starts, options.uls);
        } else {
          stage_context = std::make_unique<RowsContext>(stage.phi, stage.y, stage.labels, stage.rational, stretch_starts, options.uls);
        }
        const FitContext& staged = *stage_context;
        std::vector<Index> all(static_cast<std::size_t>(staged.terms()));
        for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<Index>(i);
        if (scored_samples >= 0 && staged.samples() != scored_samples)
          throw std::invalid_argument("selection: hook returned " + std::to_string(staged.samples()) +
                                      " samples, earlier models had " + std::to_string(scored_samples) +
                                      " (AIC needs the same N)");
        scored_samples = staged.samples();
        score(staged, prune(staged, std::move(all), options, threshold, model, stage.kept), model);
      } else {
        if (scored_samples >= 0 && base.samples() != scored_samples)
          throw std::invalid_argument("selection: models scored on different sample counts");
        scored_samples = base.samples();
        const std::vector<Index> kept = prune(base, ranked, options, threshold, model, kept_columns);
        std::vector<Index> key = kept;
        std::sort(key.begin(), key.end());
        const auto seen = scored.find(key);
        if (seen != scored.end()) {
          // Several j often prune to the same term set: same fit, same score, no data pass.
          const CandidateModel& twin = out.candidates[seen->second];
          model.columns = twin.columns;
          model.t_test = twin.t_test;
          model.residual_mean = twin.residual_mean;
          model.aic = twin.aic;
          model.fit = twin.fit;  // residuals may have been released; the twin keeps priority
          model.ok = true;
        } else {
          score(base, kept, model);
          scored.emplace(std::move(key), out.candidates.size());
        }
      }
    } catch (const IdentifiabilityError& e) {
      model.ok = false;
      model.failure = e.what();
    } catch (const std::runtime_error& e) {
      model.ok = false;
      model.failure = e.what();
    }
    out.candidates.push_back(std::move(model));
    // Keep residuals only for the running best, so memory does not grow with the models tried.
    // Ties (several j pruned to the same model) go to the smaller model, then the smaller j.
    CandidateModel& m = out.candidates.back();
    if (!m.ok) continue;
    const std::size_t index = out.candidates.size() - 1;
    if (best < 0) {
      best = static_cast<std::ptrdiff_t>(index);
      continue;
    }
    CandidateModel& b = out.candidates[static_cast<std::size_t>(best)];
    const double ms = log_score(m), bs = log_score(b);
    const bool better = ms > bs + 1e-9 || (ms >= bs - 1e-9 && m.fit.theta.size() < b.fit.theta.size());
    if (better) {
      b.fit.residuals = Eigen::VectorXd();
      best = static_cast<std::ptrdiff_t>(index);
    } else {
      m.fit.residuals = Eigen::VectorXd();
    }
  }

  // Step 14: relative likelihood and fitness over the models that could be fitted.
  Eigen::VectorXd aics(static_cast<Eigen::Index>(out.candidates.size()));
  for (std::size_t i = 0; i < out.candidates.size(); ++i)
    aics[static_cast<Eigen::Index>(i)] =
        out.candidates[i].ok ? out.candidates[i].aic : std::numeric_limits<double>::quiet_NaN();
  const Eigen::VectorXd p_aic = relative_likelihood(aics);
  for (std::size_t i = 0; i < out.candidates.size(); ++i) {
    CandidateModel& m = out.candidates[i];
    if (!m.ok) continue;
    m.p_aic = p_aic[static_cast<Eigen::Index>(i)];
    m.fitness = fitness(m.residual_mean.p_value, m.p_aic);
  }
  if (best < 0) {
    throw std::runtime_error("selection: no candidate model could be fitted" +
                             (out.candidates.empty() ? std::string() : ": " + out.candidates.front().failure));
  }
  out.best = static_cast<std::size_t>(best);  // step 15: highest fitness (same order as log_score)
  return out;
}

}  // namespace

SelectionResult select_model(const SelectionProblem& problem, const SelectionOptions& options, FitHook* hook) {
  std::string why;
  if (!options.is_valid(&why)) throw std::invalid_argument("selection options: " + why);
  const RowsContext base(problem.phi, problem.y, problem.labels, problem.rational, problem.stretch_starts, options.uls);
  return select_on(base, problem.ranking, problem.kept, problem.stretch_starts, options, hook);
}

SelectionResult select_model(const NormalEquations& equations, std::vector<Index> ranking, const std::vector<Index>& kept,
                             const SelectionOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw std::invalid_argument("selection options: " + why);
  const EquationsContext base(equations, options.uls);
  return select_on(base, std::move(ranking), kept, {}, options, nullptr);
}

}  // namespace inertia::ident
