#include "analyzer/ident/selection.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numbers>
#include <random>
#include <set>

namespace inertia::ident {
namespace {

// 20 candidate columns from three random inputs with lags 0..2, squares and products; y from a
// random 5-term subset with coefficients of magnitude 0.5..1.5 and either sign, plus white noise.
struct SparseCase {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
  std::vector<std::string> labels;
  std::set<std::string> true_terms;
  std::vector<double> true_theta;  // by column
};

SparseCase sparse_case(unsigned seed, Eigen::Index n, double sigma) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Index total = n + 2;
  Eigen::MatrixXd u(total, 3);
  for (Eigen::Index k = 0; k < total; ++k)
    for (int i = 0; i < 3; ++i) u(k, i) = g(rng);
  SparseCase c;
  c.phi.resize(n, 20);
  c.labels = {"1"};
  for (int i = 0; i < 3; ++i)
    for (int lag = 0; lag <= 2; ++lag)
      c.labels.push_back("u" + std::to_string(i + 1) + (lag ? "[k-" + std::to_string(lag) + "]" : ""));
  c.labels.insert(c.labels.end(), {"u1^2", "u2^2", "u3^2", "u1*u2", "u1*u3", "u2*u3", "u1[k-1]^2",
                                   "u2[k-1]*u3[k-1]", "u1*u2[k-1]", "u3*u3[k-2]"});
  for (Eigen::Index r = 0; r < n; ++r) {
    const Eigen::Index k = r + 2;
    int col = 0;
    c.phi(r, col++) = 1.0;
    for (int i = 0; i < 3; ++i)
      for (int lag = 0; lag <= 2; ++lag) c.phi(r, col++) = u(k - lag, i);
    const double u1 = u(k, 0), u2 = u(k, 1), u3 = u(k, 2);
    c.phi.row(r).tail(10) << u1 * u1, u2 * u2, u3 * u3, u1 * u2, u1 * u3, u2 * u3,
        u(k - 1, 0) * u(k - 1, 0), u(k - 1, 1) * u(k - 1, 2), u1 * u(k - 1, 1), u3 * u(k - 2, 2);
  }
  std::vector<int> order(20);
  for (int i = 0; i < 20; ++i) order[static_cast<std::size_t>(i)] = i;
  std::shuffle(order.begin(), order.end(), rng);
  std::uniform_real_distribution<double> mag(0.5, 1.5);
  c.true_theta.assign(20, 0.0);
  for (int i = 0; i < 5; ++i) {
    const int j = order[static_cast<std::size_t>(i)];
    c.true_theta[static_cast<std::size_t>(j)] = mag(rng) * (rng() % 2 ? 1.0 : -1.0);
    c.true_terms.insert(c.labels[static_cast<std::size_t>(j)]);
  }
  c.y = c.phi * Eigen::Map<const Eigen::VectorXd>(c.true_theta.data(), 20);
  for (Eigen::Index r = 0; r < n; ++r) c.y[r] += sigma * g(rng);
  return c;
}

// Figures for one noise level and alpha: exact structures out of `seeds`, and parameters within
// 3 reported sd of the truth out of all parameters of the selected models.
struct Recovery {
  int exact = 0, params = 0, within = 0;
};

Recovery recovery(double sigma, double alpha, int seeds) {
  Recovery r;
  SelectionOptions options;
  options.alpha = alpha;
  for (int s = 0; s < seeds; ++s) {
    const SparseCase c = sparse_case(1000 + s, 2000, sigma);
    const SelectionProblem problem(c.phi, c.y, c.labels);
    const SelectionResult result = select_model(problem, options);
    const CandidateModel& best = result.best_model();
    const std::set<std::string> chosen(best.fit.labels.begin(), best.fit.labels.end());
    r.exact += chosen == c.true_terms;
    for (std::size_t i = 0; i < best.columns.size(); ++i) {
      const double truth = c.true_theta[static_cast<std::size_t>(best.columns[i])];
      ++r.params;
      r.within += std::abs(best.fit.theta[static_cast<Eigen::Index>(i)] - truth) <=
                  3.0 * best.fit.std_dev[static_cast<Eigen::Index>(i)];
    }
  }
  return r;
}

// Section 2.7.2 on 20 candidates, 5 true terms, 40 seeds, three noise levels. The t-test is
// family-wise (Bonferroni over the candidates), so the exact structure is expected in about
// 1 - alpha of the seeds: at alpha = 0.01 the bar of 38/40 is a real test (P(fail) < 1%); at the
// default alpha = 0.05 about 2 failures of 40 are expected, so only 36/40 is asserted there.
TEST(Selection, RecoversSparseModelsAtThreeNoiseLevels) {
  const int seeds = 40;
  for (double sigma : {0.1, 0.5, 2.0}) {
    for (double alpha : {0.01, 0.05}) {
      const Recovery r = recovery(sigma, alpha, seeds);
      std::cout << "[ selection ] sigma " << sigma << ", alpha " << alpha << ": exact structure "
                << r.exact << "/" << seeds << ", parameters within 3 sd " << r.within << "/"
                << r.params << "\n";
      EXPECT_GE(r.exact, alpha == 0.01 ? 38 : 36) << "sigma " << sigma << " alpha " << alpha;
      EXPECT_GE(double(r.within), 0.95 * double(r.params)) << "sigma " << sigma;
    }
  }
}

// The hook replaces the fitted problem (algorithm 2 steps 6-8). A transform whose effect is known
// exactly: the F_S problem is the F_E one with y scaled by 2, so every parameter doubles.
class DoublingHook final : public FitHook {
 public:
  explicit DoublingHook(const SparseCase& c) : c_(c) {}
  bool transform(std::size_t j, const UlsResult& ranked_fit, StageProblem& stage) override {
    EXPECT_EQ(ranked_fit.theta.size(), static_cast<Eigen::Index>(j));
    stage.phi = c_.phi;
    stage.y = 2.0 * c_.y;
    stage.labels = c_.labels;
    ++calls;
    return true;
  }
  int calls = 0;

 private:
  const SparseCase& c_;
};

TEST(Selection, HookReplacesTheScoredProblem) {
  const SparseCase c = sparse_case(5, 2000, 0.1);
  const SelectionProblem problem(c.phi, c.y, c.labels);
  SelectionOptions options;
  options.max_terms = 6;
  DoublingHook hook(c);
  const SelectionResult plain = select_model(problem, options);
  const SelectionResult hooked = select_model(problem, options, &hook);
  EXPECT_EQ(hook.calls, 6);
  ASSERT_TRUE(hooked.best_model().transformed);
  // The hooked stage holds all 20 columns; pruning must reduce them to the true 5 again.
  const std::set<std::string> chosen(hooked.best_model().fit.labels.begin(),
                                     hooked.best_model().fit.labels.end());
  EXPECT_EQ(chosen, c.true_terms);
  for (std::size_t i = 0; i < hooked.best_model().columns.size(); ++i) {
    const Eigen::Index col = hooked.best_model().columns[i];
    const double truth = c.true_theta[static_cast<std::size_t>(col)];
    EXPECT_NEAR(hooked.best_model().fit.theta[static_cast<Eigen::Index>(i)], 2.0 * truth,
                4.0 * hooked.best_model().fit.std_dev[static_cast<Eigen::Index>(i)]);
  }
  EXPECT_FALSE(plain.best_model().transformed);
}

// The same stage given by its sums (StageProblem::equations and residuals) instead of its rows:
// the same candidates, pruning, scores and best model, to rounding.
class StageHook final : public FitHook {
 public:
  StageHook(const SparseCase& c, bool by_sums) : c_(c), by_sums_(by_sums) {}
  bool transform(std::size_t, const UlsResult&, StageProblem& stage) override {
    const Eigen::VectorXd y = 2.0 * c_.y;
    stage.labels = c_.labels;
    if (by_sums_) {
      stage.equations = NormalEquations::from_rows(c_.phi, y, c_.labels);
      stage.residuals = [this, y](std::span<const Index> columns, const Eigen::VectorXd& theta) {
        ++residual_passes;
        Eigen::VectorXd out = y;
        for (std::size_t k = 0; k < columns.size(); ++k) out -= theta(Index(k)) * c_.phi.col(columns[k]);
        return out;
      };
    } else {
      stage.phi = c_.phi;
      stage.y = y;
    }
    return true;
  }
  int residual_passes = 0;

 private:
  const SparseCase& c_;
  bool by_sums_;
};

TEST(Selection, AStageGivenByItsSumsScoresAsItsRows) {
  const SparseCase c = sparse_case(5, 2000, 0.1);
  const SelectionProblem problem(c.phi, c.y, c.labels);
  SelectionOptions options;
  options.max_terms = 6;
  StageHook rows(c, false), sums(c, true);
  const SelectionResult by_rows = select_model(problem, options, &rows);
  const SelectionResult by_sums = select_model(problem, options, &sums);
  EXPECT_GT(sums.residual_passes, 0);
  ASSERT_EQ(by_sums.candidates.size(), by_rows.candidates.size());
  EXPECT_EQ(by_sums.best, by_rows.best);
  for (std::size_t k = 0; k < by_rows.candidates.size(); ++k) {
    const CandidateModel& a = by_rows.candidates[k];
    const CandidateModel& b = by_sums.candidates[k];
    ASSERT_EQ(a.ok, b.ok) << k;
    EXPECT_EQ(a.columns, b.columns) << k;
    EXPECT_EQ(a.removed, b.removed) << k;
    EXPECT_NEAR(b.aic, a.aic, 1e-9 * std::abs(a.aic)) << k;
    EXPECT_NEAR(b.residual_mean.p_value, a.residual_mean.p_value, 1e-9) << k;
    EXPECT_NEAR(b.fitness, a.fitness, 1e-9) << k;
    ASSERT_EQ(b.fit.theta.size(), a.fit.theta.size()) << k;
    for (Eigen::Index j = 0; j < a.fit.theta.size(); ++j) {
      EXPECT_NEAR(b.fit.theta(j), a.fit.theta(j), 1e-9 * a.fit.std_dev(j)) << k << " " << j;
      EXPECT_NEAR(b.fit.std_dev(j), a.fit.std_dev(j), 1e-9 * a.fit.std_dev(j)) << k << " " << j;
    }
  }
  // Noise lags need the rows: a hook that gives sums for them is the caller's error.
  SelectionOptions els = options;
  els.uls.noise_lags = 2;
  EXPECT_THROW((void)select_model(problem, els, &sums), std::invalid_argument);
}

// A hook's nuisance column (StageProblem::kept) survives step 9 whatever its t, and is fitted in
// the scored model; without `kept` the same column, pure noise, is pruned.
class NuisanceHook final : public FitHook {
 public:
  NuisanceHook(const SparseCase& c, bool keep) : c_(c), keep_(keep) {}
  bool transform(std::size_t, const UlsResult&, StageProblem& stage) override {
    std::mt19937_64 rng(99);
    std::normal_distribution<double> g(0.0, 1.0);
    stage.phi.resize(c_.phi.rows(), c_.phi.cols() + 1);
    stage.phi.leftCols(c_.phi.cols()) = c_.phi;
    for (Eigen::Index r = 0; r < c_.phi.rows(); ++r) stage.phi(r, c_.phi.cols()) = g(rng);
    stage.y = c_.y;
    stage.labels = c_.labels;
    stage.labels.push_back("nuisance");
    stage.kept.clear();
    if (keep_) stage.kept.push_back(c_.phi.cols());
    return true;
  }

 private:
  const SparseCase& c_;
  bool keep_;
};

TEST(Selection, KeptColumnsAreNeverPruned) {
  const SparseCase c = sparse_case(5, 2000, 0.1);
  const SelectionProblem problem(c.phi, c.y, c.labels);
  SelectionOptions options;
  options.max_terms = 3;
  for (bool keep : {true, false}) {
    NuisanceHook hook(c, keep);
    const SelectionResult result = select_model(problem, options, &hook);
    const CandidateModel& best = result.best_model();
    std::set<std::string> chosen(best.fit.labels.begin(), best.fit.labels.end());
    EXPECT_EQ(chosen.count("nuisance"), keep ? 1u : 0u);
    chosen.erase("nuisance");
    EXPECT_EQ(chosen, c.true_terms) << "keep " << keep;
    EXPECT_EQ(std::count(best.removed.begin(), best.removed.end(), "nuisance"), keep ? 0 : 1);
  }
}

// A bias beside a candidate near collinear with it (an input whose mean is far from zero: a
// gyro's g-sensitivity to the p axis on a rate table whose mean tilt is not zero). Without the
// bias kept, step 9 drops the weaker of the pair, which is often the bias, and the candidate then
// carries the bias at a large t; kept, the bias stays and the candidate's t is its own.
TEST(Selection, AKeptBiasIsNotReplacedByACandidateCollinearWithIt) {
  constexpr int kSeeds = 40;
  constexpr Eigen::Index n = 4000;
  int bias_lost = 0, bias_lost_kept = 0, candidate_named_kept = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    std::mt19937_64 rng(900 + static_cast<unsigned>(seed));
    std::normal_distribution<double> g(0.0, 1.0);
    Eigen::MatrixXd phi(n, 3);
    Eigen::VectorXd y(n);
    for (Eigen::Index k = 0; k < n; ++k) {
      const double input = g(rng), tilt = 0.8 + 0.05 * std::sin(2.0 * std::numbers::pi * double(k) / 1000.0);
      phi.row(k) << input, 1.0, tilt;
      y(k) = 1.5 * input + 0.02 + 0.2 * g(rng);   // white: the selection's own t-test is exact
    }
    SelectionProblem problem(phi, y, {"u", "1", "tilt"}, OutputMultiplied(), {0, 1, 2});
    for (const bool keep : {false, true}) {
      problem.kept = keep ? std::vector<Index>{0, 1} : std::vector<Index>{};
      const SelectionResult result = select_model(problem, SelectionOptions{});
      const CandidateModel& best = result.best_model();
      const std::set<std::string> chosen(best.fit.labels.begin(), best.fit.labels.end());
      (keep ? bias_lost_kept : bias_lost) += chosen.count("1") == 0 ? 1 : 0;
      if (keep) candidate_named_kept += chosen.count("tilt");
    }
  }
  std::printf("bias left out in %d of %d seeds; kept: %d, tilt named %d\n", bias_lost, kSeeds, bias_lost_kept, candidate_named_kept);
  EXPECT_GT(bias_lost, 0) << "the case this guards against";
  EXPECT_EQ(bias_lost_kept, 0);
  EXPECT_LE(candidate_named_kept, 2) << "a spurious term at the selection's 1 % family-wise level, 40 seeds";
}

// Section 2.7.2 on the normal equations alone (the live estimator's) against the rows: the same
// ranking, pruning and scores, so the same model; its coefficients and classical sd to rounding.
// AIC differs only by the residual energy taken from the statistics; step 12 here by N_eff, since
// these equations hold no successive differences (the next test gives them).
TEST(Selection, OnTheNormalEquationsSelectsWhatTheRowsSelect) {
  constexpr int kSeeds = 40;
  int same = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    const SparseCase c = sparse_case(3000 + static_cast<unsigned>(seed), 2000, 0.5);
    std::vector<Index> kept{0};   // the bias, as every fit of a sensor keeps it
    SelectionProblem problem(c.phi, c.y, c.labels);
    problem.kept = kept;
    const SelectionResult rows = select_model(problem, SelectionOptions{});
    const NormalEquations equations = NormalEquations::from_rows(c.phi, c.y, c.labels);
    const SelectionResult statistics = select_model(equations, {}, kept, SelectionOptions{});
    EXPECT_EQ(statistics.ranking, rows.ranking) << "seed " << seed;
    const CandidateModel& a = rows.best_model();
    const CandidateModel& b = statistics.best_model();
    if (a.columns != b.columns) {
      ADD_FAILURE() << "seed " << seed << ": rows and normal equations chose different models";
      continue;
    }
    ++same;
    EXPECT_EQ(a.removed, b.removed) << "seed " << seed;
    EXPECT_TRUE(b.fit.residuals.size() == 0);
    for (Eigen::Index j = 0; j < a.fit.theta.size(); ++j) {
      EXPECT_NEAR(b.fit.theta(j), a.fit.theta(j), 1e-9 * std::abs(a.fit.theta(j)) + 1e-12) << "seed " << seed;
      EXPECT_NEAR(b.fit.std_dev(j), a.fit.std_dev(j), 1e-9 * a.fit.std_dev(j)) << "seed " << seed;
    }
    EXPECT_NEAR(b.aic, a.aic, 1e-6 * std::abs(a.aic)) << "seed " << seed;
    EXPECT_NEAR(b.residual_mean.mean, a.residual_mean.mean, 1e-9) << "seed " << seed;
  }
  EXPECT_EQ(same, kSeeds);
}

// Step 12 on the normal equations reads the residual's lag-1 correlation from the successive
// differences' Gram matrix (NormalEquations::set_successive_differences), as the rows' test reads
// it from the residuals: with AR(1) noise (r1 = 0.6) in three stacked stretches, the same N_eff and
// p_res, and the same model. A pair across two stretches would count in neither.
TEST(Selection, OnTheNormalEquationsStepTwelveReadsTheRowsLagOneCorrelation) {
  constexpr int kSeeds = 20;
  const std::vector<Index> starts{700, 1300};
  for (int seed = 0; seed < kSeeds; ++seed) {
    SparseCase c = sparse_case(5000 + static_cast<unsigned>(seed), 2000, 0.0);
    std::mt19937_64 rng(6000 + static_cast<unsigned>(seed));
    std::normal_distribution<double> g(0.0, 0.5);
    double e = 0.0;
    for (Index k = 0; k < c.y.size(); ++k) {
      if (k == 0 || std::find(starts.begin(), starts.end(), k) != starts.end()) e = 0.0;
      e = 0.6 * e + g(rng);
      c.y(k) += e;
    }
    const std::vector<Index> kept{0};
    SelectionProblem problem(c.phi, c.y, c.labels);
    problem.kept = kept;
    problem.stretch_starts = starts;
    const SelectionResult rows = select_model(problem, SelectionOptions{});
    NormalEquations equations = NormalEquations::from_rows(c.phi, c.y, c.labels);
    equations.set_successive_differences(c.phi, c.y, starts);
    EXPECT_EQ(equations.difference_pairs(), 2000 - 3);
    const SelectionResult statistics = select_model(equations, {}, kept, SelectionOptions{});
    const CandidateModel& a = rows.best_model();
    const CandidateModel& b = statistics.best_model();
    ASSERT_EQ(a.columns, b.columns) << "seed " << seed;
    EXPECT_LT(a.residual_mean.effective_samples, 0.4 * 2000.0) << "seed " << seed << ": the noise's correlation is seen";
    EXPECT_NEAR(b.residual_mean.lag1_autocorrelation, a.residual_mean.lag1_autocorrelation, 1e-9) << "seed " << seed;
    EXPECT_NEAR(b.residual_mean.effective_samples, a.residual_mean.effective_samples, 1e-9 * a.residual_mean.effective_samples)
        << "seed " << seed;
    EXPECT_NEAR(b.residual_mean.p_value, a.residual_mean.p_value, 1e-9) << "seed " << seed;
    for (std::size_t j = 0; j < rows.candidates.size(); ++j) {
      if (!rows.candidates[j].ok || !statistics.candidates[j].ok) continue;
      EXPECT_NEAR(statistics.candidates[j].residual_mean.effective_samples, rows.candidates[j].residual_mean.effective_samples,
                  1e-8 * rows.candidates[j].residual_mean.effective_samples)
          << "seed " << seed << ", j " << j + 1;
    }
  }
}

// Without the bias among the candidates the statistics cannot give the residual's mean: step 12 is
// not tested there (p_res = 1, mean NaN), and noise lags, which need the residuals, are refused.
TEST(Selection, OnTheNormalEquationsWithoutABiasTheMeanIsNotTested) {
  SparseCase c = sparse_case(7, 1000, 0.2);
  std::vector<Index> columns;
  for (Index j = 1; j < c.phi.cols(); ++j) columns.push_back(j);
  Eigen::MatrixXd phi(c.phi.rows(), static_cast<Index>(columns.size()));
  std::vector<std::string> labels;
  for (std::size_t i = 0; i < columns.size(); ++i) {
    phi.col(static_cast<Index>(i)) = c.phi.col(columns[i]);
    labels.push_back(c.labels[static_cast<std::size_t>(columns[i])]);
  }
  const NormalEquations equations = NormalEquations::from_rows(phi, c.y, labels);
  const SelectionResult result = select_model(equations, {}, {}, SelectionOptions{});
  EXPECT_TRUE(std::isnan(result.best_model().residual_mean.mean));
  EXPECT_EQ(result.best_model().residual_mean.p_value, 1.0);
  SelectionOptions els;
  els.uls.noise_lags = 1;
  EXPECT_THROW((void)select_model(equations, {}, {}, els), std::invalid_argument);
}

TEST(Selection, FailedCandidateIsReportedNotFatal) {
  SparseCase c = sparse_case(6, 500, 0.1);
  c.phi.col(19) = c.phi.col(1) * 2.0;  // "u3*u3[k-2]" made a copy of "u1"
  const std::vector<Index> ranking{1, 19, 2, 3};  // a given ranking that forces the pair together
  const SelectionProblem problem(c.phi, c.y, c.labels, OutputMultiplied(), ranking);
  const SelectionResult result = select_model(problem, SelectionOptions{});
  ASSERT_EQ(result.candidates.size(), 4u);
  EXPECT_TRUE(result.candidates[0].ok);
  EXPECT_FALSE(result.candidates[1].ok);
  EXPECT_NE(result.candidates[1].failure.find("u3*u3[k-2]"), std::string::npos);
  EXPECT_TRUE(result.best_model().ok);
}

}  // namespace
}  // namespace inertia::ident
