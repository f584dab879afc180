#include "analyzer/online/information.hpp"

#include <algorithm>
#include <stdexcept>

#include "analyzer/procedure/prewhitening.hpp"

namespace inertia::online {

using Eigen::Index;

RowProducts::RowProducts(Index base, Index filtered, std::size_t nodes)
    : gram_(base), cross_(nodes, Eigen::MatrixXd::Zero(filtered, base + 1)), pairs_(nodes) {
  for (std::size_t k = 0; k < nodes; ++k)
    for (std::size_t d = 0; d < CornerGrid::kStencil && k + d < nodes; ++d) pairs_[k].push_back(Eigen::MatrixXd::Zero(filtered, filtered));
}

void RowProducts::add(const Eigen::Ref<const Eigen::MatrixXd>& base, const std::vector<Eigen::MatrixXd>& filtered,
                      const Eigen::Ref<const Eigen::VectorXd>& y) {
  const Index n = base.rows();
  if (n == 0) return;
  gram_.add(base, y);
  const Index b = base.cols();
  for (std::size_t k = 0; k < cross_.size(); ++k) {
    const auto f = filtered[k].topRows(n);
    cross_[k].leftCols(b).noalias() += f.transpose() * base;
    cross_[k].col(b).noalias() += f.transpose() * y;
    for (std::size_t d = 0; d < pairs_[k].size(); ++d) pairs_[k][d].noalias() += f.transpose() * filtered[k + d].topRows(n);
  }
}

void RowProducts::add(const RowProducts& other) {
  gram_.matrix() += other.gram_.matrix();
  for (std::size_t k = 0; k < cross_.size(); ++k) {
    cross_[k] += other.cross_[k];
    for (std::size_t d = 0; d < pairs_[k].size(); ++d) pairs_[k][d] += other.pairs_[k][d];
  }
}

void RowProducts::subtract(const RowProducts& other) {
  gram_.matrix() -= other.gram_.matrix();
  for (std::size_t k = 0; k < cross_.size(); ++k) {
    cross_[k] -= other.cross_[k];
    for (std::size_t d = 0; d < pairs_[k].size(); ++d) pairs_[k][d] -= other.pairs_[k][d];
  }
}

void RowProducts::scale(double factor) {
  gram_.matrix() *= factor;
  for (std::size_t k = 0; k < cross_.size(); ++k) {
    cross_[k] *= factor;
    for (auto& m : pairs_[k]) m *= factor;
  }
}

void RowProducts::clear() {
  gram_.matrix().setZero();
  for (std::size_t k = 0; k < cross_.size(); ++k) {
    cross_[k].setZero();
    for (auto& m : pairs_[k]) m.setZero();
  }
}

Eigen::MatrixXd RowProducts::pair(int a, int b) const {
  if (a <= b) return pairs_[static_cast<std::size_t>(a)][static_cast<std::size_t>(b - a)];
  return pairs_[static_cast<std::size_t>(b)][static_cast<std::size_t>(a - b)].transpose();
}

Eigen::MatrixXd RowProducts::model_gram(const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                        const CornerWeights& corner) const {
  const Eigen::MatrixXd& g = gram_.matrix();
  const Index b = g.rows() - 1;
  const Index p = t_base.rows();
  Eigen::MatrixXd out(p + 1, p + 1);
  const Eigen::MatrixXd tg = t_base * g.topLeftCorner(b, b);
  out.topLeftCorner(p, p).noalias() = tg * t_base.transpose();
  out.topRightCorner(p, 1).noalias() = t_base * g.topRightCorner(b, 1);
  out(p, p) = g(b, b);
  if (corner.filtered() && t_filtered.cols() > 0) {
    // F = sum_j w_j F_j: its products with [B y] and with itself from the nodes' products.
    const Index f = t_filtered.cols();
    Eigen::MatrixXd fby = Eigen::MatrixXd::Zero(f, b + 1);
    Eigen::MatrixXd ff = Eigen::MatrixXd::Zero(f, f);
    for (const auto& [j, wj] : corner.nodes) {
      fby += wj * cross_[static_cast<std::size_t>(j)];
      for (const auto& [l, wl] : corner.nodes) ff += wj * wl * pair(j, l);
    }
    const Eigen::MatrixXd mixed = t_filtered * fby.leftCols(b) * t_base.transpose();
    out.topLeftCorner(p, p) += mixed + mixed.transpose();
    out.topLeftCorner(p, p).noalias() += t_filtered * ff * t_filtered.transpose();
    out.topRightCorner(p, 1).noalias() += t_filtered * fby.col(b);
  }
  out.bottomLeftCorner(1, p) = out.topRightCorner(p, 1).transpose();
  return out;
}

Information::Information(Index base, Index filtered, std::size_t nodes)
    : rows_(base, filtered, nodes), differences_(base, filtered, nodes) {}

void Information::add(const Eigen::Ref<const Eigen::MatrixXd>& base, const std::vector<Eigen::MatrixXd>& filtered,
                      const Eigen::Ref<const Eigen::VectorXd>& y) {
  const Index n = base.rows();
  if (n == 0) return;
  rows_.add(base, filtered, y);
  const Index b = base.cols();
  if (!run_open_) {
    Run r;
    r.base = Eigen::VectorXd::Zero(b + 1);
    r.filtered.assign(rows_.nodes(), Eigen::VectorXd::Zero(rows_.nodes() == 0 ? 0 : rows_.cross(0).rows()));
    runs_.push_back(std::move(r));
    run_open_ = true;
  }
  Run& run = runs_.back();
  const auto c = base.col(0);   // the constant, through the noise model's A(q): A(1) on every row
  run.base.head(b).noalias() += base.transpose() * c;
  run.base(b) += y.dot(c);
  for (std::size_t k = 0; k < rows_.nodes(); ++k) run.filtered[k].noalias() += filtered[k].topRows(n).transpose() * c;
  run.samples += n;
  samples_ += n;
  weight_ += static_cast<double>(n);
}

void Information::add_differences(const Eigen::Ref<const Eigen::MatrixXd>& base, const std::vector<Eigen::MatrixXd>& filtered,
                                  const Eigen::Ref<const Eigen::VectorXd>& y) {
  differences_.add(base, filtered, y);
  difference_weight_ += static_cast<double>(base.rows());
}

namespace {
/// [u 1]'[u 1] of the rows `inputs` added to `gram`.
void add_input_rows(Eigen::Matrix4d& gram, const Eigen::Ref<const Eigen::MatrixX3d>& inputs) {
  gram.topLeftCorner<3, 3>().noalias() += inputs.transpose() * inputs;
  const Eigen::RowVector3d sums = inputs.colwise().sum();
  gram.block<1, 3>(3, 0) += sums;
  gram.block<3, 1>(0, 3) += sums.transpose();
  gram(3, 3) += static_cast<double>(inputs.rows());
}
}  // namespace

void Information::add_inputs(const Eigen::Ref<const Eigen::MatrixX3d>& inputs) {
  if (inputs.rows() == 0) return;
  add_input_rows(inputs_, inputs);
  if (run_open_) add_input_rows(runs_.back().inputs, inputs);   // else the rows went before a run opened
}

void Information::add(const Information& other, bool continues_run) {
  inputs_ += other.inputs_;
  if (other.samples_ == 0) return;
  if (samples_ == 0 && weight_ == 0.0) {   // no rows yet (a default-constructed one has no size either)
    const Eigen::Matrix4d inputs = inputs_;
    *this = other;
    inputs_ = inputs;
    run_open_ = false;
    return;
  }
  auto from = other.runs_.begin();
  if (continues_run && !runs_.empty() && from != other.runs_.end()) {
    Run& last = runs_.back();
    last.base += from->base;
    for (std::size_t k = 0; k < last.filtered.size(); ++k) last.filtered[k] += from->filtered[k];
    last.samples += from->samples;
    last.inputs += from->inputs;
    ++from;
  }
  runs_.insert(runs_.end(), from, other.runs_.end());
  run_open_ = false;   // rows added after another's are not its run's
  rows_.add(other.rows_);
  differences_.add(other.differences_);
  samples_ += other.samples_;
  weight_ += other.weight_;
  difference_weight_ += other.difference_weight_;
}

void Information::subtract(const Information& other) {
  // The runs are not taken out: whose they were is not known here (runs() stays as it was).
  inputs_ -= other.inputs_;
  rows_.subtract(other.rows_);
  differences_.subtract(other.differences_);
  samples_ -= other.samples_;
  weight_ -= other.weight_;
  difference_weight_ -= other.difference_weight_;
}

void Information::scale(double factor) {
  inputs_ *= factor;
  for (Run& r : runs_) {
    r.base *= factor;
    r.inputs *= factor;
    for (Eigen::VectorXd& f : r.filtered) f *= factor;
  }
  rows_.scale(factor);
  differences_.scale(factor);
  weight_ *= factor;
  difference_weight_ *= factor;
}

void Information::clear() {
  inputs_.setZero();
  runs_.clear();
  run_open_ = false;
  rows_.clear();
  differences_.clear();
  samples_ = 0;
  weight_ = 0.0;
  difference_weight_ = 0.0;
}

Eigen::VectorXd Information::constant_products(const Eigen::VectorXd& base_sums,
                                               const std::vector<Eigen::VectorXd>& filtered_sums,
                                               const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                               const CornerWeights& corner) {
  const Index b = base_sums.size() - 1;
  const Index p = t_base.rows();
  Eigen::VectorXd out(p + 1);
  out.head(p).noalias() = t_base * base_sums.head(b);
  out(p) = base_sums(b);
  if (corner.filtered() && t_filtered.cols() > 0) {
    Eigen::VectorXd f = Eigen::VectorXd::Zero(t_filtered.cols());
    for (const auto& [j, wj] : corner.nodes) f += wj * filtered_sums[static_cast<std::size_t>(j)];
    out.head(p).noalias() += t_filtered * f;
  }
  return out;
}

Eigen::VectorXd Information::model_constant_products(const Eigen::MatrixXd& t_base, const Eigen::MatrixXd& t_filtered,
                                                     const CornerWeights& corner) const {
  std::vector<Eigen::VectorXd> filtered;
  filtered.reserve(rows_.nodes());
  for (std::size_t k = 0; k < rows_.nodes(); ++k) filtered.emplace_back(rows_.cross(k).col(0));
  return constant_products(rows_.base_gram().col(0), filtered, t_base, t_filtered, corner);
}

Eigen::VectorXd Information::run_constant_products(std::size_t r, const Eigen::MatrixXd& t_base,
                                                   const Eigen::MatrixXd& t_filtered, const CornerWeights& corner) const {
  return constant_products(runs_[r].base, runs_[r].filtered, t_base, t_filtered, corner);
}

void RunStatistics::close_run() {
  if (!last_open_) return;
  closed_.add(runs_.back().info, runs_.back().joins_previous);
  last_open_ = false;
}

void RunStatistics::add(RunStatistics&& other) {
  close_run();
  other.close_run();
  closed_.add(other.closed_);   // another segment: its first cluster is a new one
  runs_.insert(runs_.end(), std::make_move_iterator(other.runs_.begin()), std::make_move_iterator(other.runs_.end()));
  other.clear();
}

void RunStatistics::scale(double factor) {
  closed_.scale(factor);
  for (Run& r : runs_) r.info.scale(factor);
}

void RunStatistics::clear() {
  closed_ = Information();
  runs_.clear();
  last_open_ = false;
}

Information RunStatistics::total() const {
  Information out = closed_;
  if (last_open_) out.add(runs_.back().info, runs_.back().joins_previous);
  return out;
}

std::int64_t RunStatistics::samples() const {
  std::int64_t n = 0;
  for (const Run& r : runs_) n += r.info.samples();
  return n;
}

SegmentPipeline::SegmentPipeline(Eigen::VectorXd ar, std::vector<Index> filtered_sources, std::vector<double> corners,
                                 double sample_period_s, bool successive_differences)
    : ar_(std::move(ar)), sources_(std::move(filtered_sources)), corners_(std::move(corners)), period_(sample_period_s),
      differences_(successive_differences),
      highpass_(corners_.size(), std::vector<procedure::HighpassState>(sources_.size())),
      last_filtered_(corners_.size()), filtered_(corners_.size()), filtered_differences_(corners_.size()) {}

void SegmentPipeline::push(const Eigen::Ref<const Eigen::MatrixXd>& base, const Eigen::Ref<const Eigen::VectorXd>& y,
                           Information& info) {
  const Index n = base.rows();
  if (n == 0) return;
  const Index b = base.cols();
  const Index m = ar_.size();
  // [history; block] of [B y], then A(q) on every column: z(k) = x(k) - sum a_j x(k - j).
  const Index have = std::min<Index>(m, rows_in_);
  raw_.resize(have + n, b + 1);
  if (have > 0) raw_.topRows(have) = history_.bottomRows(have);
  raw_.bottomRows(n).leftCols(b) = base;
  raw_.bottomRows(n).col(b) = y;
  // Rows whose whole A(q) window lies in the segment: the first m rows of a segment are lost.
  const Index first = std::max<Index>(0, m - rows_in_);   // first usable row of the block
  const Index out = n - std::min(first, n);
  rows_in_ += n;
  if (m > 0) {
    history_.resize(std::min<Index>(m, have + n), b + 1);
    history_ = raw_.bottomRows(history_.rows());
  }
  if (out == 0) return;
  const Index at = have + (n - out);   // position in raw_ of the first output row
  procedure::ar_filter(ar_, raw_.middleRows(at - m, out + m), white_);
  for (std::size_t k = 0; k < corners_.size(); ++k) {
    Eigen::MatrixXd& f = filtered_[k];
    f.resize(out, static_cast<Index>(sources_.size()));
    for (std::size_t s = 0; s < sources_.size(); ++s) {
      f.col(static_cast<Index>(s)) = white_.col(sources_[s]);
      procedure::highpass_in_place(f.col(static_cast<Index>(s)), corners_[k], period_, highpass_[k][s]);
    }
  }
  info.add(white_.leftCols(b), filtered_, white_.col(b));
  if (!differences_) return;
  // Each row less the one before it, the segment's first row excepted.
  const Index pairs = has_last_ ? out : out - 1;
  if (pairs > 0) {
    const auto difference = [&](const Eigen::MatrixXd& rows, const Eigen::RowVectorXd& last, Eigen::MatrixXd& into) {
      into.resize(pairs, rows.cols());
      if (has_last_) into.row(0) = rows.row(0) - last;
      into.bottomRows(out - 1) = rows.bottomRows(out - 1) - rows.topRows(out - 1);
    };
    difference(white_, last_white_, white_differences_);
    for (std::size_t k = 0; k < corners_.size(); ++k) difference(filtered_[k], last_filtered_[k], filtered_differences_[k]);
    info.add_differences(white_differences_.leftCols(b), filtered_differences_, white_differences_.col(b));
  }
  last_white_ = white_.row(out - 1);
  for (std::size_t k = 0; k < corners_.size(); ++k) last_filtered_[k] = filtered_[k].row(out - 1);
  has_last_ = true;
}

}  // namespace inertia::online
