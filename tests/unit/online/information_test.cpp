// The live estimator's sufficient statistics (online/information.hpp) against the products of
// the rows computed directly: the Gram matrices, the model's Gram at any corner weights, the
// runs' constant products, the inputs' Gram; merging, subtracting and scaling against
// accumulating the rows; and the segment pipeline against A(q) and the high pass written here.
#include "analyzer/online/information.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/support/reference_highpass.hpp"

namespace inertia::online {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr Index kBase = 4, kFiltered = 2;
constexpr std::size_t kNodes = 5;
constexpr double kConstant = 0.7;   // base column 0: the constant through A(q), A(1) on every row

struct Rows {
  MatrixXd base;                   // n x kBase, column 0 the constant
  std::vector<MatrixXd> filtered;  // per node, n x kFiltered
  VectorXd y;
  Eigen::MatrixX3d inputs;
};

Rows random_rows(Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Rows r;
  r.base = MatrixXd::NullaryExpr(n, kBase, [&] { return g(rng); });
  r.base.col(0).setConstant(kConstant);
  r.base.col(2).array() += 3.0;   // a column with a mean
  for (std::size_t k = 0; k < kNodes; ++k) r.filtered.push_back(MatrixXd::NullaryExpr(n, kFiltered, [&] { return g(rng); }));
  r.y = VectorXd::NullaryExpr(n, [&] { return 2.0 + g(rng); });
  r.inputs = Eigen::MatrixX3d::NullaryExpr(n, 3, [&] { return 9.8 * g(rng); });
  return r;
}

Rows slice(const Rows& r, Index from, Index n) {
  Rows s;
  s.base = r.base.middleRows(from, n);
  for (const MatrixXd& f : r.filtered) s.filtered.push_back(f.middleRows(from, n));
  s.y = r.y.segment(from, n);
  s.inputs = r.inputs.middleRows(from, n);
  return s;
}

void add_rows(Information& info, const Rows& r) {
  info.add(r.base, r.filtered, r.y);
  info.add_inputs(r.inputs);
}

/// [Phi y] of the model whose columns are B t_base' + (sum_j w_j F_j) t_filtered'.
MatrixXd model_columns(const Rows& r, const MatrixXd& t_base, const MatrixXd& t_filtered, const CornerWeights& w) {
  MatrixXd phi = r.base * t_base.transpose();
  if (w.filtered()) {
    MatrixXd f = MatrixXd::Zero(r.y.size(), kFiltered);
    for (const auto& [node, weight] : w.nodes) f += weight * r.filtered[static_cast<std::size_t>(node)];
    phi += f * t_filtered.transpose();
  }
  MatrixXd out(phi.rows(), phi.cols() + 1);
  out << phi, r.y;
  return out;
}

double max_relative(const MatrixXd& got, const MatrixXd& expected) {
  return (got - expected).cwiseAbs().maxCoeff() / expected.cwiseAbs().maxCoeff();
}

struct Transform {
  MatrixXd base, filtered;
};

Transform random_transform(Index p, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  return {MatrixXd::NullaryExpr(p, kBase, [&] { return g(rng); }), MatrixXd::NullaryExpr(p, kFiltered, [&] { return g(rng); })};
}

/// Corner weights to check: static, one node, and stencils of two to four neighbouring nodes.
std::vector<CornerWeights> corner_cases() {
  return {CornerWeights{}, CornerWeights{{{2, 1.0}}}, CornerWeights{{{0, 0.4}, {1, 0.6}}},
          CornerWeights{{{1, -0.1}, {2, 0.7}, {3, 0.5}, {4, -0.1}}}};
}

TEST(Information, GramOfTheRowsAddedInBlocks) {
  const Rows all = random_rows(300, 1);
  Information info(kBase, kFiltered, kNodes);
  add_rows(info, slice(all, 0, 1));
  add_rows(info, slice(all, 1, 120));
  add_rows(info, slice(all, 121, 179));
  MatrixXd by(300, kBase + 1);
  by << all.base, all.y;
  EXPECT_LT(max_relative(info.base_gram(), by.transpose() * by), 1e-13);
  EXPECT_EQ(info.samples(), 300);
  EXPECT_EQ(info.weight(), 300.0);
  MatrixXd a1(300, 4);
  a1 << all.inputs, VectorXd::Ones(300);
  EXPECT_LT(max_relative(info.input_gram(), a1.transpose() * a1), 1e-13);
}

TEST(Information, ModelGramIsThatOfTheModelsColumns) {
  const Rows all = random_rows(400, 2);
  Information info(kBase, kFiltered, kNodes);
  add_rows(info, slice(all, 0, 250));
  add_rows(info, slice(all, 250, 150));
  const Transform t = random_transform(3, 3);
  for (const CornerWeights& w : corner_cases()) {
    const MatrixXd py = model_columns(all, t.base, t.filtered, w);
    EXPECT_LT(max_relative(info.model_gram(t.base, t.filtered, w), py.transpose() * py), 1e-13) << w.nodes.size() << " nodes";
    // [Phi y]' c with c the constant base column.
    const VectorXd c = VectorXd::Constant(400, kConstant);
    EXPECT_LT(max_relative(info.model_constant_products(t.base, t.filtered, w), py.transpose() * c), 1e-13);
  }
}

TEST(Information, RunsKeepTheirOwnConstantProducts) {
  const Rows all = random_rows(300, 4);
  Information info(kBase, kFiltered, kNodes);
  add_rows(info, slice(all, 0, 100));   // run 0
  info.start_run();
  add_rows(info, slice(all, 100, 60));  // run 1, in two blocks
  add_rows(info, slice(all, 160, 90));
  info.start_run();
  add_rows(info, slice(all, 250, 50));  // run 2
  ASSERT_EQ(info.runs(), 3u);
  EXPECT_EQ(info.run_samples(0), 100);
  EXPECT_EQ(info.run_samples(1), 150);
  EXPECT_EQ(info.run_samples(2), 50);
  const Transform t = random_transform(2, 5);
  const Index from[3] = {0, 100, 250}, rows[3] = {100, 150, 50};
  for (const CornerWeights& w : corner_cases()) {
    for (std::size_t r = 0; r < 3; ++r) {
      const MatrixXd py = model_columns(slice(all, from[r], rows[r]), t.base, t.filtered, w);
      const VectorXd expected = py.transpose() * VectorXd::Constant(rows[r], kConstant);
      EXPECT_LT(max_relative(info.run_constant_products(r, t.base, t.filtered, w), expected), 1e-13) << "run " << r;
    }
  }
}

TEST(Information, MergingEqualsAccumulatingEveryRow) {
  const Rows all = random_rows(500, 6);
  Information whole(kBase, kFiltered, kNodes), first(kBase, kFiltered, kNodes), second(kBase, kFiltered, kNodes);
  add_rows(whole, all);
  add_rows(first, slice(all, 0, 200));
  add_rows(second, slice(all, 200, 300));
  const Transform t = random_transform(3, 7);

  Information merged = first;
  merged.add(second);
  EXPECT_EQ(merged.samples(), 500);
  EXPECT_EQ(merged.weight(), 500.0);
  EXPECT_LT(max_relative(merged.base_gram(), whole.base_gram()), 1e-13);
  EXPECT_LT(max_relative(merged.input_gram(), whole.input_gram()), 1e-13);
  for (const CornerWeights& w : corner_cases())
    EXPECT_LT(max_relative(merged.model_gram(t.base, t.filtered, w), whole.model_gram(t.base, t.filtered, w)), 1e-13);
  ASSERT_EQ(merged.runs(), 2u) << "another's rows are its own run";
  EXPECT_EQ(merged.run_samples(0), 200);
  EXPECT_EQ(merged.run_samples(1), 300);

  // The same phase across the two: one run, whose products are those of all the rows.
  Information joined = first;
  joined.add(second, true);
  ASSERT_EQ(joined.runs(), 1u);
  EXPECT_EQ(joined.run_samples(0), 500);
  for (const CornerWeights& w : corner_cases())
    EXPECT_LT(max_relative(joined.run_constant_products(0, t.base, t.filtered, w),
                           whole.model_constant_products(t.base, t.filtered, w)),
              1e-13);

  // Onto an empty (default-constructed) one: the other's statistics.
  Information empty;
  empty.add(whole);
  EXPECT_EQ(empty.samples(), 500);
  EXPECT_LT(max_relative(empty.base_gram(), whole.base_gram()), 1e-15);
  EXPECT_LT(max_relative(empty.input_gram(), whole.input_gram()), 1e-15);
  EXPECT_LT(max_relative(empty.model_gram(t.base, t.filtered, corner_cases()[3]),
                         whole.model_gram(t.base, t.filtered, corner_cases()[3])),
            1e-15);

  // Taking the second part out again leaves the first's.
  Information left = whole;
  left.subtract(second);
  EXPECT_EQ(left.samples(), 200);
  EXPECT_EQ(left.weight(), 200.0);
  EXPECT_LT(max_relative(left.base_gram(), first.base_gram()), 1e-12);
  EXPECT_LT(max_relative(left.input_gram(), first.input_gram()), 1e-12);
  for (const CornerWeights& w : corner_cases())
    EXPECT_LT(max_relative(left.model_gram(t.base, t.filtered, w), first.model_gram(t.base, t.filtered, w)), 1e-12);
}

TEST(Information, ScaleWeighsEverySampleLess) {
  const Rows all = random_rows(200, 8);
  Information info(kBase, kFiltered, kNodes);
  add_rows(info, all);
  Information scaled = info;
  scaled.scale(0.25);
  const Transform t = random_transform(2, 9);
  EXPECT_EQ(scaled.samples(), 200) << "the count of rows stays";
  EXPECT_EQ(scaled.weight(), 50.0);
  EXPECT_LT(max_relative(scaled.base_gram(), 0.25 * info.base_gram()), 1e-15);
  EXPECT_LT(max_relative(scaled.input_gram(), 0.25 * info.input_gram()), 1e-15);
  for (const CornerWeights& w : corner_cases()) {
    EXPECT_LT(max_relative(scaled.model_gram(t.base, t.filtered, w), 0.25 * info.model_gram(t.base, t.filtered, w)), 1e-15);
    EXPECT_LT(max_relative(scaled.run_constant_products(0, t.base, t.filtered, w), 0.25 * info.run_constant_products(0, t.base, t.filtered, w)),
              1e-15);
  }
  scaled.clear();
  EXPECT_EQ(scaled.samples(), 0);
  EXPECT_EQ(scaled.runs(), 0u);
  EXPECT_EQ(scaled.base_gram(), MatrixXd::Zero(kBase + 1, kBase + 1));
}

TEST(RunStatistics, RunsPerPhaseAndTheirSum) {
  const Rows all = random_rows(400, 10);
  const auto empty = [] { return Information(kBase, kFiltered, kNodes); };
  RunStatistics stats;
  add_rows(stats.run_for(0, 0, empty), slice(all, 0, 100));     // phase 0, label 0
  add_rows(stats.run_for(1, 1, empty), slice(all, 100, 50));    // phase 1, label 1
  add_rows(stats.run_for(1, 1, empty), slice(all, 150, 50));    // phase 1 goes on: the same run
  add_rows(stats.run_for(2, 1, empty), slice(all, 200, 200));   // phase 2, label 1 again
  ASSERT_EQ(stats.runs().size(), 3u);
  EXPECT_EQ(stats.runs()[1].info.samples(), 100);
  EXPECT_FALSE(stats.runs()[1].joins_previous);
  EXPECT_TRUE(stats.runs()[2].joins_previous) << "the previous run's label";
  EXPECT_EQ(stats.samples(), 400);
  Information whole(kBase, kFiltered, kNodes);
  add_rows(whole, all);
  const Information total = stats.total();
  EXPECT_EQ(total.samples(), 400);
  EXPECT_LT(max_relative(total.base_gram(), whole.base_gram()), 1e-13);
  EXPECT_LT(max_relative(total.input_gram(), whole.input_gram()), 1e-13);
  // Phases 1 and 2 share a label: one cluster of 300 rows after phase 0's 100.
  ASSERT_EQ(total.runs(), 2u);
  EXPECT_EQ(total.run_samples(0), 100);
  EXPECT_EQ(total.run_samples(1), 300);
  stats.scale(0.5);
  EXPECT_EQ(stats.total().weight(), 200.0);
}

using inertia::testing::reference_highpass;

TEST(SegmentPipeline, ChunksGiveTheFilteredRowsOfTheWholeSegment) {
  // A(q) = 1 - 0.5 q^-1 + 0.2 q^-2 on [B y], the first two rows lost; the high pass at each corner
  // on base columns 1 and 3 of the whitened rows, starting settled at the first whitened row.
  const Index n = 400, m = 2;
  const Eigen::Vector2d ar(0.5, -0.2);
  const std::vector<Index> sources{1, 3};
  const std::vector<double> corners{100.0, 800.0};
  const double period = 1e-3;
  std::mt19937_64 rng(12);
  std::normal_distribution<double> g(0.0, 1.0);
  MatrixXd raw = MatrixXd::NullaryExpr(n, kBase, [&] { return g(rng); });
  raw.col(0).setOnes();
  const VectorXd y = VectorXd::NullaryExpr(n, [&] { return g(rng); });

  MatrixXd white(n - m, kBase + 1);
  for (Index k = m; k < n; ++k) {
    Eigen::RowVectorXd row(kBase + 1), before1(kBase + 1), before2(kBase + 1);
    row << raw.row(k), y(k);
    before1 << raw.row(k - 1), y(k - 1);
    before2 << raw.row(k - 2), y(k - 2);
    white.row(k - m) = row - 0.5 * before1 + 0.2 * before2;
  }
  Rows expected;
  expected.base = white.leftCols(kBase);
  expected.y = white.col(kBase);
  for (const double b : corners) {
    MatrixXd f(n - m, 2);
    for (std::size_t s = 0; s < sources.size(); ++s) f.col(static_cast<Index>(s)) = reference_highpass(white.col(sources[s]), b, period);
    expected.filtered.push_back(f);
  }
  EXPECT_NEAR(white(0, 0), 1.0 - 0.5 + 0.2, 1e-15) << "the constant column becomes A(1)";

  SegmentPipeline pipeline(ar, sources, corners, period, true);
  Information info(kBase, 2, corners.size());
  Index at = 0;
  for (const Index len : {Index{1}, Index{1}, Index{5}, Index{93}, Index{300}}) {
    pipeline.push(raw.middleRows(at, len), y.segment(at, len), info);
    at += len;
  }
  ASSERT_EQ(at, n);
  EXPECT_EQ(pipeline.rows_in(), n);
  EXPECT_EQ(info.samples(), n - m);
  MatrixXd by(n - m, kBase + 1);
  by << expected.base, expected.y;
  EXPECT_LT(max_relative(info.base_gram(), by.transpose() * by), 1e-12);
  std::mt19937_64 trng(13);
  const MatrixXd tb = MatrixXd::NullaryExpr(3, kBase, [&] { return g(trng); });
  const MatrixXd tf = MatrixXd::NullaryExpr(3, 2, [&] { return g(trng); });
  for (const CornerWeights& w : {CornerWeights{{{0, 1.0}}}, CornerWeights{{{1, 1.0}}}, CornerWeights{{{0, 0.3}, {1, 0.7}}}}) {
    MatrixXd f = MatrixXd::Zero(n - m, 2);
    for (const auto& [node, weight] : w.nodes) f += weight * expected.filtered[static_cast<std::size_t>(node)];
    MatrixXd py(n - m, 4);
    py << expected.base * tb.transpose() + f * tf.transpose(), expected.y;
    EXPECT_LT(max_relative(info.model_gram(tb, tf, w), py.transpose() * py), 1e-12);
    // Step 12's successive differences: each whitened row less the one before, across the chunks.
    const MatrixXd dpy = py.bottomRows(n - m - 1) - py.topRows(n - m - 1);
    EXPECT_LT(max_relative(info.model_difference_gram(tb, tf, w), dpy.transpose() * dpy), 1e-12);
  }
  EXPECT_EQ(info.difference_weight(), static_cast<double>(n - m - 1));

  // A second segment of the same rows: its first row pairs with nothing of the first segment's.
  SegmentPipeline second(ar, sources, corners, period, true);
  second.push(raw.topRows(150), y.head(150), info);
  second.push(raw.bottomRows(n - 150), y.tail(n - 150), info);
  EXPECT_EQ(info.difference_weight(), static_cast<double>(2 * (n - m - 1)));
  const CornerWeights w{{{0, 0.3}, {1, 0.7}}};
  MatrixXd py(n - m, 4);
  py << expected.base * tb.transpose() + (0.3 * expected.filtered[0] + 0.7 * expected.filtered[1]) * tf.transpose(), expected.y;
  const MatrixXd dpy = py.bottomRows(n - m - 1) - py.topRows(n - m - 1);
  EXPECT_LT(max_relative(info.model_difference_gram(tb, tf, w), 2.0 * dpy.transpose() * dpy), 1e-12);

  // A given model's fit reads no differences: a pipeline told so adds none.
  Information rows_only(kBase, 2, corners.size());
  SegmentPipeline without(ar, sources, corners, period, false);
  without.push(raw, y, rows_only);
  EXPECT_EQ(rows_only.samples(), n - m);
  EXPECT_EQ(rows_only.difference_weight(), 0.0);
  EXPECT_LT(max_relative(rows_only.base_gram(), by.transpose() * by), 1e-12);
}

}  // namespace
}  // namespace inertia::online
