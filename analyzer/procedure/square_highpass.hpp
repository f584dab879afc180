#pragma once
// Eq. 12's K_jj(s) a_j^2 terms: the squares of the sensor-frame accelerations pass a first-order
// high pass s / (s + b) before they reach the output. One definition, used where the squares are
// fitted (pipeline), simulated (model_simulation) and stored (model file key
// square_highpass_rad_s): the bilinear transform prewarped at b, started settled (output 0 on the
// first sample),
//   h(k) = p h(k-1) + g (x(k) - x(k-1)),  c = b / tan(b T / 2),  p = (c - b)/(c + b),  g = c/(c + b).
#include <Eigen/Dense>

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// True for a_i^2, a_p^2, a_o^2 (at any lag): the terms the high pass applies to.
bool is_square_term(const ident::Term& term);

/// The recursion's p and g above for a corner at a sample period.
struct HighpassCoefficients {
  double p = 0.0, g = 0.0;
};
HighpassCoefficients highpass_coefficients(double corner_rad_s, double sample_period_s);

/// Filters x in place with s / (s + corner) at the sample period.
void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s);

/// The filter's memory between blocks of one signal (the online estimator filters chunk by chunk).
struct HighpassState {
  double previous_input = 0.0, output = 0.0;
  bool started = false;   // false: the next block starts settled, as highpass_in_place does
};

/// The same filter continued from `state` (updated): blocks filtered one after another give
/// exactly what highpass_in_place gives on their concatenation.
void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s,
                       HighpassState& state);

/// The high pass on `columns` of `x`, case by case over the rows of `layout` (a filter never
/// runs across two cases).
void highpass_columns(Eigen::MatrixXd& x, const std::vector<Eigen::Index>& columns, const std::vector<CaseRows>& layout,
                      const dataset::Dataset& data, double corner_rad_s);

/// The largest corner every case of `layout` can be filtered with (below Nyquist); 0 when a case
/// has no sample period.
double max_corner(const std::vector<CaseRows>& layout, const dataset::Dataset& data);

/// Eq. 12's corner b from data: the residual sum of squares of the least-squares fit of y on
/// every column of a stacked problem when its square columns pass s / (s + b) (or stay static).
/// The Gram matrix of the columns is computed once; each corner costs one pass over the rows in
/// blocks: the square columns filtered into a block-sized buffer and multiplied with the block's
/// columns while it is in cache, so a corner allocates nothing of the record's length and reads
/// the stack once. The blocks' products are added in block order: the same bits on any number of
/// threads (parallel::jobs). Used where a model's squares are fitted
/// (pipeline) and where a model without them is diagnosed (diagnose).
class SquareCornerSearch {
 public:
  /// Corners of the log-spaced grid the search starts from (least_residual_corner refines the best).
  static constexpr int kGridCorners = 13;

  SquareCornerSearch(const StackedRegression& s, std::vector<Eigen::Index> squares, const dataset::Dataset& data);

  [[nodiscard]] double rss(std::optional<double> corner_rad_s) const;
  /// rss at each of `corners` (rad/s), the same bits as one call per corner, from one pass over
  /// the rows: each block's columns are read once for every corner while they are in cache.
  [[nodiscard]] std::vector<double> rss(std::span<const double> corners_rad_s) const;

  /// The corner minimizing rss over [lo, hi] by least_residual_corner (corner_search.hpp) on a
  /// log-spaced grid of kGridCorners, or nullopt when the static squares fit better. lo == hi:
  /// that corner (given, not searched).
  [[nodiscard]] std::optional<double> best(double lo, double hi) const;

 private:
  static constexpr Eigen::Index kBlockRows = 1024;   // a block's filtered squares stay in L1/L2
  /// Blocks whose products are formed side by side before they are added, in block order: what a
  /// pass holds is bounded by the window, not the record, and the sums are those of one thread.
  static constexpr std::size_t kWindowBlocks = 64;

  struct Block {
    std::size_t layout_index = 0;   // into s_.cases
    Eigen::Index begin = 0, rows = 0;
    bool starts_case = false;
  };
  /// The filtered square columns' products over rows: with every column (cross, n x p), with
  /// themselves (gram, n x n) and with y.
  struct FilteredProducts {
    Eigen::MatrixXd cross, gram;
    Eigen::VectorXd y;
  };
  /// One thread's filter of the squares over blocks at a pass's corners: the block's filtered
  /// squares (column c * squares + i is square i at corner c), those columns' addresses, and each
  /// column's high-pass coefficients at the sample period of the case last filtered (worked out
  /// again only when a block starts another case).
  struct BlockFilter {
    Eigen::MatrixXd out;
    std::vector<double*> columns;
    std::vector<HighpassCoefficients> coefficients;
    std::size_t layout_index = SIZE_MAX;
  };

  [[nodiscard]] BlockFilter block_filter(std::size_t corners) const;
  /// The squares' high pass over `block` at each of `corners_rad_s` (highpass_in_place; as many
  /// as `filter` was made for), continued from `state` (one per corner and square, corner-major;
  /// updated), into filter.out's first block.rows rows.
  void filter_block(const Block& block, std::span<const double> corners_rad_s, std::span<HighpassState> state,
                    BlockFilter& filter) const;
  /// Block b's products at each corner into `out` (one per corner), the filter continued from
  /// `state` (updated).
  void block_products(std::size_t b, std::span<const double> corners_rad_s, std::span<HighpassState> state, BlockFilter& filter,
                      std::span<FilteredProducts> out) const;
  /// The products at each corner, in one pass over the blocks.
  [[nodiscard]] std::vector<FilteredProducts> filtered_products(std::span<const double> corners_rad_s) const;
  /// The residual of the fit with the squares' products `filtered` (nullptr: the static squares).
  [[nodiscard]] double rss_with(const FilteredProducts* filtered) const;

  const StackedRegression& s_;
  std::vector<Eigen::Index> squares_;
  const dataset::Dataset& data_;
  Eigen::MatrixXd gram_;
  Eigen::VectorXd xty_;
  double yy_ = 0.0;
  std::vector<Block> blocks_;   // every case's rows in blocks of kBlockRows, in stack order
};

}  // namespace inertia::procedure
