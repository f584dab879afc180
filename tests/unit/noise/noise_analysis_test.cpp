// The noise analysis of a dataset (analyzer/noise/noise_analysis.hpp): static stretches found and
// pooled across a gap, white noise's N recovered, the PSD at the level the fit predicts, a tau the
// data cannot reach clipped and said, and a dataset without rest refused by name.
#include "analyzer/noise/noise_analysis.hpp"
#include "analyzer/noise/noise_fit.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <random>

#include "common/input_error.hpp"

namespace inertia::noise {
namespace {

dataset::CaseData rest_case(const std::string& name, Eigen::Index n, double sd, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sd);
  dataset::CaseData c;
  c.name = name;
  c.kind = CaseKind::Static;
  c.sample_period_s = 1e-3;
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * 1e-3);
  c.a_e = dataset::Matrix3Columns::Zero(n, 3);
  c.y.resize(n);
  for (Eigen::Index k = 0; k < n; ++k) c.y(k) = 3.0 + g(rng);
  return c;
}

TEST(NoiseAnalysis, WhiteNoiseOfTwoStretchesPooled) {
  dataset::Dataset d;
  d.output_unit = "mA";
  d.cases = {rest_case("pose-1", 60000, 0.01, 1), rest_case("pose-2", 40000, 0.01, 2)};
  NoiseAnalysisOptions o;
  o.fit.terms = {false, true, true, true, false};
  const NoiseAnalysis a = analyse_noise(d, o);
  ASSERT_EQ(a.stretches.size(), 2u);
  ASSERT_TRUE(a.fit.has_value()) << a.fit_error;
  const double want_n = 0.01 * std::sqrt(1e-3);
  const NoiseCoefficient& n = a.fit->terms[static_cast<std::size_t>(NoiseTerm::N)];
  EXPECT_LE(n.lower, want_n);
  EXPECT_GE(n.upper, want_n);
  EXPECT_TRUE(n.determined);
  EXPECT_FALSE(a.fit->terms[static_cast<std::size_t>(NoiseTerm::K)].determined);
  // The PSD of white noise: flat at 2 N^2 (one-sided), what model_psd gives.
  ASSERT_GT(a.psd.segments, 10);
  double mean = 0.0;
  for (double p : a.psd.density) mean += p / static_cast<double>(a.psd.density.size());
  EXPECT_NEAR(mean, model_psd(*a.fit, 10.0, 1e-3), 0.05 * mean);
  EXPECT_NEAR(mean, 2.0 * want_n * want_n, 0.05 * mean);
}

TEST(NoiseAnalysis, ATauTheDataCannotReachIsClippedAndSaid) {
  dataset::Dataset d;
  d.cases = {rest_case("short", 5000, 0.01, 3)};
  NoiseAnalysisOptions o;
  o.tau_max_s = 100.0;
  const NoiseAnalysis a = analyse_noise(d, o);
  ASSERT_FALSE(a.notes.empty());
  EXPECT_NE(a.notes.back().find("tau clipped"), std::string::npos) << a.notes.back();
  EXPECT_LT(a.points.back().tau, 5.0);
}

TEST(NoiseAnalysis, NoRestNamesWhatIsMissing) {
  dataset::Dataset d;
  dataset::CaseData c = rest_case("shaker-ia", 1000, 0.01, 4);
  c.kind = CaseKind::Shaker;
  d.cases = {c};
  try {
    (void)analyse_noise(d, {});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no static stretch"), std::string::npos) << e.what();
  }
  NoiseAnalysisOptions o;
  o.only_case = "nosuch";
  EXPECT_THROW((void)analyse_noise(d, o), InputError);
  o.only_case = "shaker-ia";
  EXPECT_NO_THROW((void)analyse_noise(d, o)) << "a case named is taken whole";
}

/// model_psd is the spectrum whose Allan variance is model_avar, for the sampled series: the
/// Allan variance at tau = m tau0 of a series of one-sided PSD S is the integral over 0 .. fs/2 of
/// S(f) 2 sin^4(pi f m tau0) / (m sin(pi f tau0))^2. Exact for Q (the sampled spectrum) and N at
/// every m; B and K are continuous-time laws, whose sampled Allan variance approaches theirs as
/// tau grows.
TEST(NoiseFit, ModelPsdIsTheSpectrumOfModelAvar) {
  constexpr double kTau0 = 1e-3;
  const auto sampled_avar = [&](const std::array<double, kNoiseTerms>& c, int m) {
    constexpr int kSteps = 400000;   // Simpson over (0, fs/2]; the integrand is smooth there
    const double top = 0.5 / kTau0, h = top / kSteps;
    double sum = 0.0;
    for (int i = 1; i <= kSteps; ++i) {
      const double f = h * i;
      const double transfer = 2.0 * std::pow(std::sin(std::numbers::pi * f * m * kTau0), 4) / std::pow(m * std::sin(std::numbers::pi * f * kTau0), 2);
      sum += (i == kSteps ? 1.0 : i % 2 == 1 ? 4.0 : 2.0) * model_psd(c, f, kTau0) * transfer;
    }
    return sum * h / 3.0;   // the f = 0 end contributes 0
  };
  for (const NoiseTerm t : {NoiseTerm::Q, NoiseTerm::N}) {
    std::array<double, kNoiseTerms> c{};
    c[static_cast<std::size_t>(t)] = 2.0;
    for (const int m : {1, 2, 3, 8, 32}) {
      const double expected = model_avar(c, m * kTau0);
      EXPECT_NEAR(sampled_avar(c, m) / expected, 1.0, 1e-6) << noise_term_name(t) << " m " << m;
    }
  }
}

}  // namespace
}  // namespace inertia::noise
