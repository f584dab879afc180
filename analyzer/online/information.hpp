#pragma once
// Sufficient statistics of the live regression, and the per-segment pipeline that feeds them.
//
// Least squares needs only inner products of its columns and the output. The live estimator keeps
// them over the basis (live_basis.hpp) instead of over the model's own columns, so the model's
// statistics for any mounting misalignment and squares' corner follow exactly:
//     Phi = B T' + F_k U'   =>   Phi'Phi = T B'B T' + T B'F_k U' + U F_k'B T' + U F_k'F_k U',
// with B the base columns, F_k the filtered columns at corner k, and T, U the coefficient rows
// of the model's terms. Statistics add over samples, so segments, cases and mountings combine
// by addition and a case can be taken out again (the convergence test leaves cases out).
//
// The noise: least squares on coloured noise is inefficient and its classical covariance too
// small (procedure/prewhitening.hpp). The pipeline filters every base column and the output with
// the noise model's A(q) (AR prewhitening, GLS) before they enter the statistics, then passes the
// squares' monomials through each corner's high pass. Both filters are linear and time-invariant,
// so the order does not matter except in the filters' start-up at a segment's first rows (the
// batch fit high-passes first); each segment loses its first order() rows, as in the batch.
#include <Eigen/Dense>

#include <cstdint>
#include <vector>

#include "analyzer/ident/err.hpp"
#include "analyzer/online/corner_grid.hpp"
#include "analyzer/procedure/square_highpass.hpp"

namespace inertia::online {

/// Products of a stretch of rows' columns: [B y]'[B y], and per corner-grid node F_k'[B y] and
/// F_k'F_{k+d} for nodes at most kStencil - 1 apart. They add over rows, so over segments and cases.
class RowProducts {
 public:
  RowProducts() = default;
  RowProducts(Eigen::Index base, Eigen::Index filtered, std::size_t nodes);

  /// Adds rows: base (n x b), the filtered columns at each node (at least n rows each), the output.
  void add(const Eigen::Ref<const Eigen::MatrixXd>& base, const std::vector<Eigen::MatrixXd>& filtered,
           const Eigen::Ref<const Eigen::VectorXd>& y);
  void add(const RowProducts& other);
  void subtract(const RowProducts& other);
  void scale(double factor);
  void clear();

  [[nodiscard]] const Eigen::MatrixXd& base_gram() const { return gram_.matrix(); }   // [B y]'[B y]
  /// F_k'[B y] of node k (f x (b + 1)).
  [[nodiscard]] const Eigen::MatrixXd& cross(std::size_t node) const { return cross_[node]; }
  [[nodiscard]] std::size_t nodes() const { return cross_.size(); }
  /// [Phi y]'[Phi y] of the model whose columns are B t_base' + F(corner) t_filtered', with
  /// F(corner) = sum_j w_j F_j over the corner's nodes (static squares: t_filtered ignored).
  [[nodiscard]] Eigen::MatrixXd model_gram(const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                           const CornerWeights& corner) const;

 private:
  /// F_a' F_b for nodes a, b at most kStencil - 1 apart.
  [[nodiscard]] Eigen::MatrixXd pair(int a, int b) const;

  ident::ErrGram gram_{0};
  std::vector<Eigen::MatrixXd> cross_;                // per node: F_k' [B y]   (f x (b + 1))
  std::vector<std::vector<Eigen::MatrixXd>> pairs_;   // per node k, per d: F_k' F_{k+d}
};

class Information {
 public:
  Information() = default;
  /// `nodes`: filtered column sets (one per corner-grid node).
  Information(Eigen::Index base, Eigen::Index filtered, std::size_t nodes);

  /// Adds rows: base (n x b), the filtered columns at each node (n x f each), the output.
  void add(const Eigen::Ref<const Eigen::MatrixXd>& base, const std::vector<Eigen::MatrixXd>& filtered,
           const Eigen::Ref<const Eigen::VectorXd>& y);
  /// Adds successive differences of rows (each row less the row before it in its segment), in the
  /// layout of add(): what step 12's lag-1 correlation of a residual reads
  /// (ident::NormalEquations::set_successive_differences).
  void add_differences(const Eigen::Ref<const Eigen::MatrixXd>& base, const std::vector<Eigen::MatrixXd>& filtered,
                       const Eigen::Ref<const Eigen::VectorXd>& y);
  /// Runs kept, oldest first: a run is a contiguous stretch of one phase of a case, the unit whose
  /// offsets the case scatter compares (LiveSolver::add_case_scatter; the batch's phase clusters).
  /// Rows added go on the last run until start_run(); add(other) appends other's (RunStatistics
  /// keeps one Information per plan phase).
  [[nodiscard]] std::size_t runs() const { return runs_.size(); }
  /// The rows added from now on form a new run (a long phase is cut into clusters of a minute).
  void start_run() { run_open_ = false; }
  [[nodiscard]] std::int64_t run_samples(std::size_t r) const { return runs_[r].samples; }
  /// input_gram() over the inputs added while run r was the last.
  [[nodiscard]] const Eigen::Matrix4d& run_input_gram(std::size_t r) const { return runs_[r].inputs; }
  /// model_constant_products over the rows of run r alone.
  [[nodiscard]] Eigen::VectorXd run_constant_products(std::size_t r, const Eigen::MatrixXd& t_base,
                                                      const Eigen::MatrixXd& t_filtered, const CornerWeights& corner) const;
  /// Adds the same rows' inputs along the case axes IRA, XRA, YRA (n x 3: specific force, or rates
  /// for a gyroscope), unfiltered: what procedure::axis_excitation reads. How much of each axis
  /// varies on its own is a property of the motion, which the noise model's filter would distort
  /// (it lifts the references' high-frequency noise against the constant inputs).
  void add_inputs(const Eigen::Ref<const Eigen::MatrixX3d>& inputs);
  /// `continues_run`: other's first run goes on this one's last (the same phase label across two
  /// plan phases: one cluster, as the batch's phase_clusters).
  void add(const Information& other, bool continues_run = false);
  void subtract(const Information& other);
  /// Exponential forgetting: every sample so far weighs `factor` less.
  void scale(double factor);
  void clear();

  [[nodiscard]] std::int64_t samples() const { return samples_; }
  [[nodiscard]] double weight() const { return weight_; }   // sum of sample weights
  [[nodiscard]] const Eigen::MatrixXd& base_gram() const { return rows_.base_gram(); }   // [B y]'[B y]
  /// [a_IRA a_XRA a_YRA 1]'[a_IRA a_XRA a_YRA 1] of the inputs added (add_inputs).
  [[nodiscard]] const Eigen::Matrix4d& input_gram() const { return inputs_; }

  /// The rows' [Phi y]'[Phi y] (RowProducts::model_gram).
  [[nodiscard]] Eigen::MatrixXd model_gram(const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                           const CornerWeights& corner) const {
    return rows_.model_gram(t_base, t_filtered, corner);
  }
  /// The successive differences' [dPhi dy]'[dPhi dy], and their weight (the differenced rows).
  [[nodiscard]] Eigen::MatrixXd model_difference_gram(const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                                      const CornerWeights& corner) const {
    return differences_.model_gram(t_base, t_filtered, corner);
  }
  [[nodiscard]] double difference_weight() const { return difference_weight_; }
  /// [Phi y]' c, c the (filtered) constant base column 0: with the noise model A(q), c = A(1) on
  /// every row, so this over A(1) sums the model's columns and the output over the rows.
  [[nodiscard]] Eigen::VectorXd model_constant_products(const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                                        const CornerWeights& corner) const;

 private:
  RowProducts rows_;
  RowProducts differences_;
  /// A run's products of the (filtered) constant base column 0 with every column and the output.
  struct Run {
    Eigen::VectorXd base;                   // [B y]' c   (b + 1)
    std::vector<Eigen::VectorXd> filtered;  // per node: F_k' c
    std::int64_t samples = 0;
    Eigen::Matrix4d inputs = Eigen::Matrix4d::Zero();   // as inputs_
  };
  /// Products of `v` (base, filtered at each node, output) with the constant, as model_constant_products.
  static Eigen::VectorXd constant_products(const Eigen::VectorXd& base_sums, const std::vector<Eigen::VectorXd>& filtered_sums,
                                           const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                           const CornerWeights& corner);

  Eigen::Matrix4d inputs_ = Eigen::Matrix4d::Zero();
  std::vector<Run> runs_;
  bool run_open_ = false;                   // the next rows continue runs_.back()
  std::int64_t samples_ = 0;
  double weight_ = 0.0;
  double difference_weight_ = 0.0;
};

/// Statistics kept per run (a contiguous phase of a case) and summed. The sum is what the estimate
/// reads; the runs let the convergence test leave one phase out where the plan has no case to
/// spare (a term that one case alone determines).
class RunStatistics {
 public:
  struct Run {
    int phase = -1;   // the plan's phase index
    int label = -1;   // the stream's phase label
    bool joins_previous = false;   // the previous run's label in the same segment: one cluster with it
    Information info;
  };
  /// Where the next rows of plan phase `phase` (labelled `label`) go: the last run while its phase
  /// goes on, else a new one, `empty()` (called only then: an empty Information is not small).
  template <class MakeEmpty>
  Information& run_for(int phase, int label, MakeEmpty&& empty) {
    if (!last_open_ || runs_.back().phase != phase) {
      close_run();
      const bool joins = !runs_.empty() && runs_.back().label == label;
      runs_.push_back({phase, label, joins, empty()});
      last_open_ = true;
    }
    return runs_.back().info;
  }
  /// Appends other's runs (closed: rows after this start a new run).
  void add(RunStatistics&& other);
  /// Exponential forgetting (Information::scale) of every run.
  void scale(double factor);
  void clear();
  /// Every row's statistics.
  [[nodiscard]] Information total() const;
  [[nodiscard]] const std::vector<Run>& runs() const { return runs_; }
  [[nodiscard]] std::int64_t samples() const;

 private:
  void close_run();

  Information closed_;      // the sum of every run but an open last one
  std::vector<Run> runs_;
  bool last_open_ = false;  // runs_.back() takes more rows (not in closed_ yet)
};

/// A segment's rows on their way into the statistics: the noise model's A(q), then each corner's
/// high pass on the squares' monomials. Keeps the filters' memory between chunks of the segment.
class SegmentPipeline {
 public:
  /// `ar`: a_1..a_m of A(q) = 1 - sum a_j q^-j (empty: white noise, no filtering);
  /// `filtered_sources`: base positions of the squares' monomials; `corners`: the grid's nodes, rad/s;
  /// `successive_differences`: whether the rows' differences enter the statistics too (what a
  /// model search's step 12 reads; a given model's fit does not, and they double the cost per row).
  SegmentPipeline(Eigen::VectorXd ar, std::vector<Eigen::Index> filtered_sources, std::vector<double> corners,
                  double sample_period_s, bool successive_differences);

  /// The next raw rows of the segment (base columns and output, in order) into `info`, with their
  /// successive differences within the segment (Information::add_differences).
  void push(const Eigen::Ref<const Eigen::MatrixXd>& base, const Eigen::Ref<const Eigen::VectorXd>& y, Information& info);
  [[nodiscard]] std::int64_t rows_in() const { return rows_in_; }

 private:
  Eigen::VectorXd ar_;
  std::vector<Eigen::Index> sources_;
  std::vector<double> corners_;
  double period_;
  bool differences_;
  std::int64_t rows_in_ = 0;
  Eigen::MatrixXd history_;   // the last order() raw rows of [B y]
  std::vector<std::vector<procedure::HighpassState>> highpass_;   // per corner, per source
  // The last row that entered the statistics, for the next chunk's first difference.
  bool has_last_ = false;
  Eigen::RowVectorXd last_white_;
  std::vector<Eigen::RowVectorXd> last_filtered_;
  // Work buffers, kept between chunks.
  Eigen::MatrixXd raw_, white_, white_differences_;
  std::vector<Eigen::MatrixXd> filtered_, filtered_differences_;
};

}  // namespace inertia::online
