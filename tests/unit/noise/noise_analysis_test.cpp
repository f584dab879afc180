// The noise analysis of a dataset (analyzer/noise/noise_analysis.hpp): static stretches found and
// pooled across a gap, white noise's N recovered, the PSD at the level the fit predicts, a tau the
// data cannot reach clipped and said, and a dataset without rest refused by name.
#include "analyzer/noise/noise_analysis.hpp"
#include "analyzer/noise/noise_fit.hpp"

#include <gtest/gtest.h>

#include <array>
#include <filesystem>
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

/// Every number of two analyses, compared bit for bit.
void expect_same_analysis(const NoiseAnalysis& a, const NoiseAnalysis& b) {
  ASSERT_EQ(a.stretches.size(), b.stretches.size());
  for (std::size_t i = 0; i < a.stretches.size(); ++i) {
    EXPECT_EQ(a.stretches[i].case_index, b.stretches[i].case_index);
    EXPECT_EQ(a.stretches[i].begin, b.stretches[i].begin);
    EXPECT_EQ(a.stretches[i].end, b.stretches[i].end);
    EXPECT_EQ(a.stretches[i].duration_s, b.stretches[i].duration_s);
  }
  EXPECT_EQ(a.tau0_s, b.tau0_s);
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    EXPECT_EQ(a.points[i].avar, b.points[i].avar) << "tau " << a.points[i].tau;
    EXPECT_EQ(std::isnan(a.points[i].mvar), std::isnan(b.points[i].mvar));
    if (!std::isnan(a.points[i].mvar)) {
      EXPECT_EQ(a.points[i].mvar, b.points[i].mvar) << "tau " << a.points[i].tau;
    }
    EXPECT_EQ(a.points[i].terms, b.points[i].terms);
  }
  ASSERT_EQ(a.fit.has_value(), b.fit.has_value());
  if (a.fit) {
    for (std::size_t t = 0; t < a.fit->terms.size(); ++t) EXPECT_EQ(a.fit->terms[t].value, b.fit->terms[t].value) << "term " << t;
  }
  EXPECT_EQ(a.psd.segments, b.psd.segments);
  EXPECT_EQ(a.psd.segment_length, b.psd.segment_length);
  EXPECT_EQ(a.psd.density, b.psd.density);
  EXPECT_EQ(a.notes, b.notes);
}

/// A dataset folder written to disk: a static case, a shaker case with rest phases between its
/// other phases (several blocks of the streamed file), and a case with another sample period.
std::filesystem::path written_dataset() {
  const std::filesystem::path dir = std::filesystem::path(INERTIA_BINARY_DIR) / "test-data" / "noise-streamed";
  std::filesystem::remove_all(dir);
  dataset::Dataset d;
  d.output_unit = "mA";
  dataset::CaseData labelled = rest_case("shaker-ia", 90000, 0.02, 6);
  labelled.kind = CaseKind::Shaker;
  labelled.phase_names = {"rest", "sine", "dwell"};
  for (Eigen::Index k = 0; k < labelled.size(); ++k)
    labelled.phase.push_back(static_cast<std::uint16_t>(k < 30000 ? 0 : k < 50000 ? 1 : k < 50030 ? 2 : k < 60000 ? 1 : 2));
  dataset::CaseData slow = rest_case("slow", 3000, 0.01, 7);
  slow.sample_period_s = 2e-3;
  slow.t = Eigen::VectorXd::LinSpaced(3000, 0.0, 2999 * 2e-3);
  d.cases = {rest_case("pose-1", 40000, 0.01, 5), labelled, slow};
  for (dataset::CaseData& c : d.cases) c.file = c.name + ".csv";
  dataset::write_dataset(dir, d);
  return dir;
}

TEST(NoiseAnalysis, AStreamedDatasetGivesTheAnalysisOfTheDatasetReadWhole) {
  const std::filesystem::path dir = written_dataset();
  const dataset::Dataset whole = dataset::read_dataset(dir);
  const NoiseAnalysis streamed = analyse_noise(dir);
  expect_same_analysis(streamed, analyse_noise(whole));
  // The labelled case's rest and dwell runs, its 30 dwell rows too few; the slow case left out.
  EXPECT_EQ(streamed.stretches.size(), 4u);
  EXPECT_NE(streamed.notes.front().find("case slow: sampled every"), std::string::npos) << streamed.notes.front();
  NoiseAnalysisOptions one;
  one.only_case = "shaker-ia";
  expect_same_analysis(analyse_noise(dir, one), analyse_noise(whole, one));
  one.only_case = "nosuch";
  EXPECT_THROW((void)analyse_noise(dir, one), InputError);
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
