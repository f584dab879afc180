#include "analyzer/ident/uls_recursive.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace inertia::ident {

bool RecursiveUlsOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& s) {
    if (why != nullptr) *why = s;
    return false;
  };
  if (!(forgetting > 0.0 && forgetting <= 1.0))
    return fail("forgetting = " + std::to_string(forgetting) + " is outside (0, 1]");
  if (!(initial_covariance > 0.0)) return fail("initial_covariance must be > 0");
  if (warmup < -1) return fail("warmup must be -1 or >= 0");
  if (compensation_iterations < 1) return fail("compensation_iterations must be >= 1");
  if (!(max_correction > 0.0 && max_correction < 1.0)) return fail("max_correction is outside (0, 1)");
  if (reset_trace < 0.0) return fail("reset_trace must be >= 0");
  if (noise_lags < 0) return fail("noise_lags must be >= 0");
  return true;
}

UlsRecursive::UlsRecursive(Index terms, std::vector<Index> output_multiplied,
                           const RecursiveUlsOptions& options, Eigen::VectorXd scale)
    : options_(options),
      np_(terms + options.noise_lags),
      terms_(terms),
      q_(static_cast<Index>(output_multiplied.size())),
      den_(std::move(output_multiplied)),
      llt_(q_),
      eig_(q_),
      lu_(q_) {
  std::string why;
  if (!options.is_valid(&why)) throw std::invalid_argument("recursive ULS options: " + why);
  if (terms < 1) throw std::invalid_argument("recursive ULS: needs at least one term");
  sign_ = Eigen::VectorXd::Ones(np_);
  for (Index c : den_) {
    if (c < 0 || c >= terms) throw std::invalid_argument("recursive ULS: output-multiplied position out of range");
    sign_[c] = -1.0;
  }
  scale_ = Eigen::VectorXd::Ones(np_);
  if (scale.size() > 0) {
    if (scale.size() != terms || !(scale.array() > 0.0).all())
      throw std::invalid_argument("recursive ULS: scale must hold one positive value per term");
    scale_.head(terms) = scale;
  }
  if (options.reset_trace > 0.0 && options.reset_trace <= options.initial_covariance * static_cast<double>(np_))
    throw std::invalid_argument("recursive ULS: reset_trace must exceed trace(P0) = " +
                                std::to_string(options.initial_covariance * static_cast<double>(np_)));
  warmup_ = options.warmup < 0 ? std::max<Index>(100, 10 * np_) : options.warmup;
  p_phi_.resize(np_);
  phi_.resize(np_);
  gain_.resize(np_);
  tmp_.resize(np_);
  history_ = Eigen::VectorXd::Zero(options.noise_lags);
  theta_ = Eigen::VectorXd::Zero(np_);
  theta_ls_ = Eigen::VectorXd::Zero(np_);
  pbb_.resize(q_, q_);
  c_.resize(q_, q_);
  a_.resize(q_, q_);
  sym_.resize(q_, q_);
  fb_.resize(q_);
  theta_b_.resize(q_);
  rhs_b_.resize(q_);
  reset_covariance();
  resets_ = 0;
}

void UlsRecursive::reset_covariance() {
  // Restart every accumulator together so that P = R^-1 and J, D, d, s11 describe the same
  // (prior-only) data; the current estimate becomes the prior mean.
  const double c = options_.initial_covariance;
  p_ = Eigen::MatrixXd::Identity(np_, np_) * c;
  r_ = Eigen::MatrixXd::Identity(np_, np_) / c;
  theta_ls_ = theta_;
  j_ = 0.0;
  d_mat_ = Eigen::MatrixXd::Zero(q_, q_);
  d_vec_ = Eigen::VectorXd::Zero(q_);
  s11_ = 0.0;
  count_ = 0;
  ++resets_;
}

void UlsRecursive::initialize(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                              const Eigen::Ref<const Eigen::VectorXd>& y,
                              const Eigen::Ref<const Eigen::MatrixXd>& factors) {
  const Index n = phi.rows();
  const Index n_e = options_.noise_lags;
  if (phi.cols() != terms_ || y.size() != n || factors.rows() != n || factors.cols() != q_)
    throw std::invalid_argument("recursive ULS initialize: block sizes do not match");
  if (n <= np_) throw std::invalid_argument("recursive ULS initialize: block too short");
  std::vector<std::string> labels;
  for (Index j = 0; j < terms_; ++j) labels.push_back("column " + std::to_string(j));
  UlsOptions batch_options;
  batch_options.noise_lags = options_.noise_lags;
  batch_options.max_correction = options_.max_correction;
  const OutputMultiplied rational{den_, factors};
  const UlsResult fit = uls_batch(phi, y, labels, rational, batch_options);

  Eigen::MatrixXd x(n, np_);
  x.leftCols(terms_) = phi;
  for (Index i = 1; i <= n_e; ++i) {
    x.col(terms_ + i - 1).setZero();
    x.col(terms_ + i - 1).tail(n - i) = fit.residuals.head(n - i);
  }
  scale_ = (x.colwise().squaredNorm().transpose() / static_cast<double>(n)).cwiseSqrt();
  for (Index j = 0; j < np_; ++j)
    if (!(scale_[j] > 0.0)) scale_[j] = 1.0;
  const Eigen::VectorXd inv = sign_.cwiseQuotient(scale_);
  const Eigen::MatrixXd xs = x * inv.asDiagonal();
  r_ = xs.transpose() * xs;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(r_);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all())
    throw std::runtime_error("recursive ULS initialize: the block's normal matrix is singular");
  p_ = ldlt.solve(Eigen::MatrixXd::Identity(np_, np_));
  theta_ls_ = p_ * (xs.transpose() * y);
  j_ = (y - xs * theta_ls_).squaredNorm();
  Eigen::MatrixXd fb(n, q_);
  for (Index a = 0; a < q_; ++a) fb.col(a) = factors.col(a) / scale_[den_[static_cast<std::size_t>(a)]];
  d_mat_ = fb.transpose() * fb;
  d_vec_ = fb.colwise().sum().transpose();
  s11_ = static_cast<double>(n);
  count_ = n;
  for (Index i = 0; i < n_e; ++i) history_[i] = fit.residuals[n - 1 - i];
  theta_ = theta_ls_;
  if (q_ > 0 && count_ >= warmup_) compensate(50, 1e-13);
}

double UlsRecursive::zeta_energy() {
  // LS Pythagoras (notes §4.3 step 5): V(theta) = J + (theta - theta_LS)' R (theta - theta_LS).
  tmp_ = theta_ - theta_ls_;
  p_phi_.noalias() = r_ * tmp_;
  return std::max(j_ + tmp_.dot(p_phi_), 0.0);
}

void UlsRecursive::compensate(int iterations, double tolerance) {
  for (int it = 0; it < iterations; ++it) {
    const double szz = zeta_energy();
    for (Index a = 0; a < q_; ++a) theta_b_[a] = theta_[den_[static_cast<std::size_t>(a)]];
    rhs_b_.noalias() = d_mat_ * theta_b_;
    const double sbb = s11_ + 2.0 * theta_b_.dot(d_vec_) + theta_b_.dot(rhs_b_);
    double sigma2 = sbb > 0.0 ? szz / sbb : 0.0;
    for (Index a = 0; a < q_; ++a)
      for (Index b = 0; b < q_; ++b)
        pbb_(a, b) = p_(den_[static_cast<std::size_t>(a)], den_[static_cast<std::size_t>(b)]);
    // PD guard: lambda_max(P_bb D) = lambda_max(L' D L) with P_bb = L L'.
    llt_.compute(pbb_);
    if (llt_.info() == Eigen::Success) {
      c_ = llt_.matrixL();
      a_.noalias() = d_mat_ * c_;
      sym_.noalias() = c_.transpose() * a_;
      eig_.compute(sym_, Eigen::EigenvaluesOnly);
      const double rho = eig_.eigenvalues()[q_ - 1];
      if (rho > 0.0) sigma2 = std::min(sigma2, options_.max_correction / rho);
    }
    sigma2_ = sigma2;
    // (I - s^2 P_bb D) theta_b = theta_LS,b + s^2 P_bb d, then theta = theta_LS + s^2 P_:,b (D theta_b + d).
    a_.noalias() = pbb_ * d_mat_;
    a_ *= -sigma2;
    a_.diagonal().array() += 1.0;
    rhs_b_.noalias() = pbb_ * d_vec_;
    rhs_b_ *= sigma2;
    for (Index a = 0; a < q_; ++a) rhs_b_[a] += theta_ls_[den_[static_cast<std::size_t>(a)]];
    lu_.compute(a_);
    theta_b_ = lu_.solve(rhs_b_);
    rhs_b_.noalias() = d_mat_ * theta_b_;
    rhs_b_ += d_vec_;
    gain_ = theta_;  // previous iterate, for the convergence test
    theta_ = theta_ls_;
    for (Index a = 0; a < q_; ++a)
      theta_.noalias() += (sigma2 * rhs_b_[a]) * p_.col(den_[static_cast<std::size_t>(a)]);
    if (tolerance > 0.0 && (theta_ - gain_).norm() <= tolerance * theta_.norm()) break;
  }
}

void UlsRecursive::update(const Eigen::Ref<const Eigen::VectorXd>& phi_row, double y,
                          const Eigen::Ref<const Eigen::VectorXd>& factors) {
  const double lambda = options_.forgetting;
  for (Index i = 0; i < terms_; ++i) phi_[i] = sign_[i] * phi_row[i] / scale_[i];
  for (Index i = 0; i < history_.size(); ++i) phi_[terms_ + i] = history_[i] / scale_[terms_ + i];

  // RLS (notes §4.1).
  p_phi_.noalias() = p_ * phi_;
  const double denom = lambda + phi_.dot(p_phi_);
  gain_ = p_phi_ / denom;
  const double eps = y - phi_.dot(theta_ls_);
  theta_ls_ += gain_ * eps;
  j_ = lambda * j_ + lambda * eps * eps / denom;
  p_.noalias() -= gain_ * p_phi_.transpose();
  p_ /= lambda;
  for (Index c = 1; c < p_.cols(); ++c)  // symmetrize: rounding must not make P indefinite
    for (Index r = 0; r < c; ++r) p_(r, c) = p_(c, r) = 0.5 * (p_(r, c) + p_(c, r));

  // Accumulators of the compensation (notes §4.3 step 3), forgetting applied to all.
  r_ *= lambda;
  r_.noalias() += phi_ * phi_.transpose();
  for (Index a = 0; a < q_; ++a) fb_[a] = factors[a] / scale_[den_[static_cast<std::size_t>(a)]];
  d_mat_ *= lambda;
  d_mat_.noalias() += fb_ * fb_.transpose();
  d_vec_ = lambda * d_vec_ + fb_;
  s11_ = lambda * s11_ + 1.0;
  ++count_;

  if (q_ > 0 && count_ >= warmup_) {
    compensate(options_.compensation_iterations, 0.0);
  } else {
    theta_ = theta_ls_;
  }

  if (history_.size() > 0) {
    // A-posteriori rational residual eps = y - a/b with the updated theta (notes §4.2: a-priori
    // residuals leave a visible bias).
    double a_num = 0.0;
    double b_den = 1.0;
    for (Index i = 0; i < np_; ++i) {
      if (sign_[i] > 0.0) a_num += theta_[i] * phi_[i];
    }
    for (Index a = 0; a < q_; ++a) b_den += theta_[den_[static_cast<std::size_t>(a)]] * fb_[a];
    for (Index i = history_.size() - 1; i > 0; --i) history_[i] = history_[i - 1];
    history_[0] = y - a_num / b_den;
  }

  if (lambda < 1.0 && options_.reset_trace > 0.0 && p_.trace() > options_.reset_trace) {
    reset_covariance();
  }
}

RecursiveEstimate UlsRecursive::estimate() const {
  UlsRecursive polished = *this;
  if (q_ > 0 && count_ >= warmup_) polished.compensate(50, 1e-13);
  RecursiveEstimate out;
  out.theta = polished.theta_.cwiseQuotient(scale_);
  const double szz = polished.zeta_energy();
  out.effective_samples = s11_;
  out.samples = count_;
  const double dof = std::max(s11_ - static_cast<double>(np_), 1.0);
  out.residual_variance = szz / dof;
  out.std_dev = (out.residual_variance * p_.diagonal().cwiseMax(0.0)).cwiseSqrt().cwiseQuotient(scale_);
  double sbb = s11_;
  for (Index a = 0; a < q_; ++a) {
    const double ta = polished.theta_[den_[static_cast<std::size_t>(a)]];
    sbb += 2.0 * ta * d_vec_[a];
    for (Index b = 0; b < q_; ++b) sbb += ta * d_mat_(a, b) * polished.theta_[den_[static_cast<std::size_t>(b)]];
  }
  out.sigma2 = sbb > 0.0 ? szz / sbb : 0.0;
  out.compensating = q_ > 0 && count_ >= warmup_;
  return out;
}

}  // namespace inertia::ident
