// The selection target through algorithm 2 (blocks 5-6 with the misalignment hook), not only
// through the hook-free engine (tests/unit/ident/selection_test.cpp): per seed, a random sparse
// true model drawn from the eq. 3 candidate set with a random order r in 0..2, a random small case
// misalignment, three orientations of one mounting under random vibration, white noise of known
// sd; estimate_mounting selects the model from the full eq. 1 candidate set (y lags included) and
// estimates M_E^S. Counted: seeds whose selected F_S terms are exactly the true ones, and
// parameters of the selected models within 3 reported sd of the truth.
//
// Coefficient sizes: the scale factor is 1 (output in m/s^2, like the reference); every other true
// term's coefficient is set so that its column contributes an rms of 2..6 noise sd over the data.
// With N = 3 x 1500 rows that is a t statistic of roughly 130..400 before correlation with other
// candidates (sign(a_i) with a_i, abs(a_i) with a_i^2 and the bias) eats into it, so every true
// term is meant to be detectable and a miss would point at the procedure, not at the data.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "analyzer/ident/candidates.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/pipeline.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace {

using namespace inertia;

constexpr double kSigma = 0.01;       // m/s^2, about 1 mg of white output noise
constexpr Eigen::Index kSamples = 1500;  // per orientation
// Samples simulated before each case and cut off: the output of the first max-lag samples cannot
// follow the model (their lagged inputs lie before the record), and left in they were outliers
// of 500-1000 noise sd that the selection fitted with y[k-1] and lagged copies of true terms.
constexpr Eigen::Index kRunIn = 2;

struct Truth {
  std::vector<std::string> terms;  // F_S spelling, as candidate_terms prints it
  std::vector<double> theta;
  frames::Dcm m_cs = frames::Dcm::Identity();
  int r = 0;
};

// The nominal M_E^C of the three orientations: the input axis along x, y and z of F_E in turn.
std::vector<frames::Dcm> orientations() {
  frames::Dcm a = frames::Dcm::Identity();
  frames::Dcm b, c;
  b << 0, 1, 0, 0, 0, 1, 1, 0, 0;
  c << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return {a, b, c};
}

dataset::Dataset simulate(unsigned seed, Truth& truth) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);

  truth.r = static_cast<int>(rng() % 3);
  // A case misalignment of up to about 1 deg about a random axis across the input axis (case x).
  // A turn about the input axis itself (twist) is unobservable: it leaves every linear term as it
  // is and turns the quadratic form into another of the same span, so algorithm 1 fixes it by
  // convention (the smallest rotation carrying the nominal input axis onto the estimated one).
  // With a twist in the truth, its true terms read in that frame are other terms (a 1 deg twist
  // turns a_p^2 into a_p^2 + 0.035 a_p*a_o), and an exact-structure count would score the
  // convention, not the selection.
  Eigen::Vector3d axis(g(rng), g(rng), g(rng));
  axis.x() = 0.0;
  axis.normalize();
  truth.m_cs = Eigen::AngleAxisd(0.0175 * u(rng), axis).toRotationMatrix().transpose();

  dataset::Dataset data;
  data.sensor = dataset::SensorKind::Accelerometer;
  data.output_unit = "m/s^2";
  const auto m_ecs = orientations();
  for (std::size_t o = 0; o < m_ecs.size(); ++o) {
    dataset::CaseData c;
    c.name = "vib-" + std::to_string(o);
    c.kind = CaseKind::Shaker;
    c.file = c.name + ".csv";
    c.m_ec = m_ecs[o];
    c.mounting = "fixture";
    c.sample_period_s = 1e-3;
    const Eigen::Index n = kSamples + kRunIn;
    c.t = Eigen::VectorXd::LinSpaced(n, 0.0, double(n - 1) * 1e-3);
    c.a_e.resize(n, 3);
    // Three-axis random vibration of 5 m/s^2 rms per axis on top of gravity (specific force up).
    for (Eigen::Index k = 0; k < n; ++k)
      c.a_e.row(k) << 5.0 * g(rng), 5.0 * g(rng), 9.81 + 5.0 * g(rng);
    c.y = Eigen::VectorXd::Zero(n);
    data.cases.push_back(std::move(c));
  }

  ident::CandidateOptions co;
  co.r = truth.r;
  co.include_output_lags = false;  // the true model is output-error; y lags stay candidates below
  std::vector<std::string> pool = ident::to_strings(
      ident::candidate_terms(dataset::SensorKind::Accelerometer, ident::ModelFrame::Sensor, co));
  pool.erase(std::remove(pool.begin(), pool.end(), std::string("a_i")), pool.end());
  std::shuffle(pool.begin(), pool.end(), rng);
  const std::size_t extra = 2 + rng() % 4;  // 3..6 terms with the scale factor
  truth.terms = {"a_i"};
  truth.terms.insert(truth.terms.end(), pool.begin(), pool.begin() + static_cast<long>(extra));
  const std::vector<ident::Term> terms = ident::parse_terms(truth.terms);

  std::vector<ident::Regression> regs;
  Eigen::VectorXd sum_sq = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(terms.size()));
  Eigen::Index rows = 0;
  for (auto& c : data.cases) {
    const frames::Dcm m_es = truth.m_cs * c.m_ec;
    regs.push_back(ident::build_regression(terms, ident::signals_from_case(c, m_es, data.t_ref), 2));
    sum_sq += regs.back().phi.colwise().squaredNorm().transpose();
    rows += regs.back().phi.rows();
  }
  truth.theta.assign(terms.size(), 0.0);
  truth.theta[0] = 1.0;
  for (std::size_t j = 1; j < terms.size(); ++j) {
    const double rms = std::sqrt(sum_sq[static_cast<Eigen::Index>(j)] / double(rows));
    truth.theta[j] = (2.0 + 4.0 * u(rng)) * kSigma / rms * (rng() % 2 ? 1.0 : -1.0);
  }
  const Eigen::Map<const Eigen::VectorXd> theta(truth.theta.data(), static_cast<Eigen::Index>(terms.size()));
  for (std::size_t o = 0; o < data.cases.size(); ++o) {
    auto& c = data.cases[o];
    const Eigen::VectorXd clean = regs[o].phi * theta;
    static_assert(kRunIn >= 2, "the truth's regressors look 2 samples back");
    for (Eigen::Index k = 0; k < c.y.size(); ++k)
      c.y[k] = (k >= regs[o].first_row ? clean[k - regs[o].first_row] : 0.0) + kSigma * g(rng);
    c.t = c.t.tail(kSamples).eval();
    c.a_e = c.a_e.bottomRows(kSamples).eval();
    c.y = c.y.tail(kSamples).eval();
  }
  return data;
}

// Measured 2026-11-22, seeds 7000..7039, RelWithDebInfo, 2-4 s: exact structure 38/40, parameters
// within 3 sd 168/171 (16/40 and 156/236 before). Separated by swapping one change at a time:
// - the first max-lag outputs held no model output (kRunIn above): they were what y[k-1] and the
//   lag-1 copies fitted; with the run-in the y lags stay out whether they are candidates or not;
// - M_E^S is estimated from the same data, so algorithm 2's F_S fits keep its tilt (a_p, a_o next
//   to a_i) free and never pruned (ident::StageProblem::kept): without that the tilt's error, a
//   per-orientation offset under gravity, went to 1, abs/sign(a_i) and the squares (31/40, 167/179
//   with the two test fixes);
// - a twist about the input axis in the truth (the axis choice above) scores algorithm 1's
//   convention, not the selection (36/40 with the other two fixes).
// The two misses left each keep one cross term with t of 3-4 next to the true terms. These seeds
// are not the rate: over seeds 7000..7099, 8000..8099 and 9000..9099 it is 278/300 (92.7%), the
// misses being chance terms with t of 3-5 (Bonferroni at alpha 0.05 admits them in about 5% of
// seeds) and y[k-l] standing in for a true a_i[k-l] (with output error and a scale factor of 1 the
// two columns differ by less than the noise). With alpha 0.01 it is 287/300 (95.7%).
TEST(SparseSelectionScenario, Algorithm2RecoversRandomSparseModelsWithMisalignment) {
  const auto start = std::chrono::steady_clock::now();
  const int seeds = 100;
  int exact = 0, params = 0, within = 0;
  for (int s = 0; s < seeds; ++s) {
    Truth truth;
    const dataset::Dataset data = simulate(7000u + unsigned(s), truth);
    procedure::PipelineOptions p;
    p.misalignment.select = true;
    p.misalignment.candidates.r = truth.r;
    // White noise of known sd and static terms: the prewhitening, the squares' high pass and the
    // IEEE exclusions (the rotation-table squares, a bias taken from elsewhere) are not part of this target.
    p.whitening_max_order = 0;
    p.square_highpass = false;
    p.ieee_1293 = {.rotation_table = false, .shaker = false};
    const procedure::MountingResult m =
        procedure::estimate_mounting(data, {0, 1, 2}, "fixture", p, "sparse-scenario");
    const std::set<std::string> chosen(m.s_fit.labels.begin(), m.s_fit.labels.end());
    const std::set<std::string> wanted(truth.terms.begin(), truth.terms.end());
    const bool same = chosen == wanted;
    exact += same;
    if (!same) {
      std::cout << "[ sparse ] seed " << s << " r " << truth.r << ": true";
      for (const auto& t : truth.terms) std::cout << ' ' << t;
      std::cout << " | selected";
      for (std::size_t i = 0; i < m.s_fit.labels.size(); ++i)
        std::cout << ' ' << m.s_fit.labels[i] << " (t " << std::lround(m.s_fit.theta[Eigen::Index(i)] / m.s_fit.std_dev[Eigen::Index(i)]) << ")";
      std::cout << "\n";
    }
    for (std::size_t i = 0; i < m.s_fit.labels.size(); ++i) {
      const auto it = std::find(truth.terms.begin(), truth.terms.end(), m.s_fit.labels[i]);
      const double t = it == truth.terms.end() ? 0.0 : truth.theta[std::size_t(it - truth.terms.begin())];
      ++params;
      within += std::abs(m.s_fit.theta[Eigen::Index(i)] - t) <= 3.0 * m.s_fit.std_dev[Eigen::Index(i)];
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << "[ sparse ] algorithm 2 with misalignment: exact structure " << exact << "/" << seeds
            << ", parameters within 3 sd " << within << "/" << params << ", " << seconds << " s\n";
  EXPECT_GE(double(exact), 0.95 * seeds);
  EXPECT_GE(double(within), 0.95 * double(params));
  EXPECT_LT(seconds, 60.0);
}

}  // namespace
