#pragma once
// Small synthetic shaker cases for the procedure's unit tests: a specific force that varies on
// every axis (a sine and noise along x, gravity and noise along y, a slow cosine and noise along
// z), a temperature ramp, and an output of 0.1 a_x, an offset and noise; each case turned in F_E
// as its spec says.
#include <Eigen/Dense>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace inertia::testing {

struct SyntheticCase {
  std::string mounting;
  Eigen::Index rows = 0;
  frames::Dcm m_ec = frames::Dcm::Identity();
};

inline dataset::Dataset synthetic_shaker_cases(const std::vector<SyntheticCase>& cases, std::uint64_t seed) {
  dataset::Dataset data;
  data.t_ref = 25.0;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const double shift = static_cast<double>(c);
    dataset::CaseData k;
    k.name = "case" + std::to_string(c);
    k.kind = dataset::CaseKind::Shaker;
    k.mounting = cases[c].mounting;
    k.sample_period_s = 1e-3;
    const Eigen::Index n = cases[c].rows;
    k.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * k.sample_period_s);
    k.a_e.resize(n, 3);
    for (Eigen::Index r = 0; r < n; ++r) {
      const double s = static_cast<double>(r) * k.sample_period_s;
      k.a_e.row(r) << 20.0 * std::sin((60.0 + 10.0 * shift) * s) + normal(rng), 9.81 + 0.3 * normal(rng),
          2.0 * std::cos(7.0 * s) + 0.1 * normal(rng);
    }
    k.temp = Eigen::VectorXd::LinSpaced(n, 20.0, 30.0 + shift);
    k.y = 0.1 * k.a_e.col(0) + Eigen::VectorXd::Constant(n, 3.0) + 0.01 * Eigen::VectorXd::NullaryExpr(n, [&] { return normal(rng); });
    k.m_ec = cases[c].m_ec;
    data.cases.push_back(std::move(k));
  }
  return data;
}

}  // namespace inertia::testing
