// characterize's result does not depend on --jobs (common/parallel.hpp): the batch procedure on
// simulated benches with one thread and with two, in-process. The threads split a regression's
// columns through the noise model's filter, the squares' high pass and the noise's transforms;
// each column's arithmetic is the same on any thread, and a sum Eigen vectorizes runs over
// buffers Eigen aligned (its split into a head and aligned packets would otherwise follow where
// the heap put them), so every number is the same bits.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "analyzer/procedure/pipeline.hpp"
#include "common/config/bench_config.hpp"
#include "common/parallel.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/simulate.hpp"

namespace {

using inertia::procedure::PipelineResult;

void expect_same(double a, double b, const std::string& what) {
  if (std::isnan(a) && std::isnan(b)) return;
  EXPECT_EQ(a, b) << what;
}

PipelineResult characterize_with_jobs(const inertia::dataset::Dataset& data, int jobs) {
  inertia::parallel::set_jobs(jobs);
  PipelineResult r = inertia::procedure::run_pipeline(data, inertia::procedure::PipelineOptions{}, "jobs");
  inertia::parallel::set_jobs(1);
  return r;
}

class JobsDoNotChangeTheResult : public ::testing::TestWithParam<const char*> {};

TEST_P(JobsDoNotChangeTheResult, OneThreadAndTwoGiveTheSameBits) {
  const inertia::config::BenchConfig bench =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / GetParam());
  const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
  const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 0);
  const PipelineResult one = characterize_with_jobs(data, 1);
  const PipelineResult two = characterize_with_jobs(data, 2);
  ASSERT_EQ(one.terms.size(), two.terms.size());
  for (std::size_t j = 0; j < one.terms.size(); ++j) {
    const std::string name = one.terms[j].to_string();
    ASSERT_EQ(name, two.terms[j].to_string());
    expect_same(one.fit.theta(static_cast<Eigen::Index>(j)), two.fit.theta(static_cast<Eigen::Index>(j)), name);
    expect_same(one.fit.std_dev(static_cast<Eigen::Index>(j)), two.fit.std_dev(static_cast<Eigen::Index>(j)), name + " sd");
  }
  EXPECT_EQ(one.whitening.size(), two.whitening.size()) << "the noise model's order";
  EXPECT_EQ(one.square_corner_rad_s.has_value(), two.square_corner_rad_s.has_value());
  if (one.square_corner_rad_s && two.square_corner_rad_s)
    expect_same(*one.square_corner_rad_s, *two.square_corner_rad_s, "the squares' corner");
  ASSERT_EQ(one.mountings.size(), two.mountings.size());
  for (std::size_t m = 0; m < one.mountings.size(); ++m) {
    EXPECT_EQ(one.mountings[m].aligned, two.mountings[m].aligned);
    for (int k = 0; k < 3; ++k) {
      const std::string what = one.mountings[m].mounting + " angle " + std::to_string(k);
      if (std::isnan(one.mountings[m].angles(k)) || std::isnan(two.mountings[m].angles(k))) {
        EXPECT_EQ(std::isnan(one.mountings[m].angles(k)), std::isnan(two.mountings[m].angles(k))) << what;
        continue;
      }
      expect_same(one.mountings[m].angles(k), two.mountings[m].angles(k), what);
      expect_same(one.mountings[m].angles_sd(k), two.mountings[m].angles_sd(k), what + " sd");
    }
  }
}

// The paper's plan at 1 kHz (two mountings, the squares' corner searched, AR whitening) and the
// thermal gyroscope (output-multiplied terms: rows kept white, the noise in the sandwich).
INSTANTIATE_TEST_SUITE_P(Benches, JobsDoNotChangeTheResult, ::testing::Values("sim-paper-daq.toml", "sim-gyro-thermal.toml"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           std::string name = info.param;
                           for (char& ch : name)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return name;
                         });

}  // namespace
