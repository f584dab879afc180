#include "analyzer/procedure/relative_twists.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>

#include "analyzer/ident/row_products.hpp"
#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/procedure/identifiable_fit.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/post_selection_inference.hpp"
#include "analyzer/procedure/turn_search.hpp"

namespace inertia::procedure {
namespace {

using ident::Term;

/// One Gauss-Newton step for parameters the columns of the fitted, whitened stack `s` are built
/// with (variable projection: the terms re-fitted at every value). `derivatives`: the fitted
/// prediction's derivative per parameter (prediction_derivative). With J~ the derivatives with
/// the fit's columns projected out, the step is (J~'J~)^-1 J~'r. `information` gets the inverse of
/// the step's covariance (J~'J~)^-1 J~'RJ~ (J~'J~)^-1, R the whitened residual's covariance per
/// noise run (`runs`) under its fitted spectrum (residual_spectrum, `below_record` below one cycle
/// per run): the parameters' information with the terms free and the residual's low-frequency
/// colour counted. A turn read from long static stretches is read from their means, which the
/// noise's flicker moves far more than the white part of the whitened residual says.
Eigen::VectorXd gauss_newton_step(const StackedRegression& s, const ident::UlsResult& fit, const Eigen::MatrixXd& derivatives,
                                  const std::vector<CaseRows>& runs, const std::function<double(double)>& below_record,
                                  Eigen::MatrixXd& information) {
  // The fit's columns X are read where they are in the stack, not copied: their Gram and
  // products are the stack's, the terms' rows and columns kept.
  std::vector<Eigen::Index> columns(static_cast<std::size_t>(fit.process_terms));
  for (std::size_t j = 0; j < columns.size(); ++j)
    columns[j] = std::find(s.labels.begin(), s.labels.end(), fit.labels[j]) - s.labels.begin();
  const Eigen::LDLT<Eigen::MatrixXd> gram(Eigen::MatrixXd(ident::gram(s.phi)(columns, columns)));
  const Eigen::MatrixXd coefficients = gram.solve(Eigen::MatrixXd(ident::cross_product(s.phi, derivatives)(columns, Eigen::all)));
  Eigen::MatrixXd projected = derivatives;
  for (std::size_t j = 0; j < columns.size(); ++j)
    projected.noalias() -= s.phi.col(columns[j]) * coefficients.row(static_cast<Eigen::Index>(j));
  const Eigen::MatrixXd jj = ident::gram(projected);
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(jj.rows(), jj.cols());
  for (const CaseRows& run : runs) {
    const noise::SegmentSpectrum spectrum = residual_spectrum(fit.residuals.segment(run.begin, run.rows), Eigen::VectorXd(), below_record);
    meat += noise::quadratic_form(spectrum, projected.middleRows(run.begin, run.rows));
  }
  const Eigen::LDLT<Eigen::MatrixXd> jj_factor(jj);
  const Eigen::MatrixXd bread = jj_factor.solve(Eigen::MatrixXd::Identity(jj.rows(), jj.cols()));
  const Eigen::MatrixXd covariance = bread * meat * bread;
  information = (0.5 * (covariance + covariance.transpose())).ldlt().solve(Eigen::MatrixXd::Identity(jj.rows(), jj.cols()));
  return jj_factor.solve(ident::cross_product(projected, fit.residuals));
}

/// The batch's turned regression on its whitened rows: each step a Gauss-Newton step of the
/// identifiable candidates' fit, with the prediction's derivatives by the batch rebuilt at moved
/// turns (prediction_derivative).
class RowTurns final : public TurnedBatch {
 public:
  RowTurns(StackedRegression& batch, std::vector<MountingResult>& mountings, const BatchRegression& batch_at,
           std::span<const Term> candidates, std::optional<double> square_corner, const dataset::Dataset& data,
           const PipelineOptions& options, std::function<double(double)> below_record, RelativeTwists& out, std::string reference)
      : batch_(batch), mountings_(mountings), batch_at_(batch_at), candidates_(candidates), square_corner_(square_corner),
        data_(data), options_(options), below_record_(std::move(below_record)), out_(out), reference_(std::move(reference)),
        nominal_(mountings.size(), Eigen::Vector3d::Zero()) {
    uls_ = options.selection.uls;
    uls_.noise_lags = 0;
    for (const MountingResult& m : mountings) start_.push_back({m.m_cs, m.twist_rad, m.twist_reference, m.angles(0)});
  }

  std::optional<TurnStep> step(std::span<const TurnParameter> parameters) override {
    std::vector<Eigen::Index> usable = identifiable_ranking(batch_, data_.sensor, options_.selection.err);
    std::vector<std::string> dropped;
    const ident::UlsResult fit = fit_identifiable(batch_, data_.sensor, usable, uls_, dropped);
    Eigen::MatrixXd derivatives(batch_.phi.rows(), static_cast<Eigen::Index>(parameters.size()));
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      derivatives.col(static_cast<Eigen::Index>(i)) =
          prediction_derivative(fit, kTurnDerivativeStepRad, batch_at_.whitener(), batch_.cases, [&](std::span<const Term> terms, double moved) {
            std::vector<Eigen::Vector3d> turns = nominal_;
            turns[parameters[i].mounting](parameters[i].axis) = moved;
            // The turn moves its mounting's cases only: the others are not built.
            return batch_at_.unwhitened(terms, mountings_, turns, square_corner_, mountings_[parameters[i].mounting].cases);
          });
    }
    TurnStep out;
    out.delta = gauss_newton_step(batch_, fit, derivatives, plan_case_rows(batch_, data_), below_record_, out.information);
    return out;
  }

  void turn(std::span<const TurnParameter> parameters, const Eigen::VectorXd& delta, const Eigen::MatrixXd& covariance) override {
    const std::vector<Eigen::Vector3d> turns = turns_of(parameters, delta, mountings_.size());
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      const TurnParameter& twist = parameters[i];
      if (twist.axis != 2) continue;
      const std::size_t k = twist.mounting;
      const auto at = static_cast<Eigen::Index>(i);
      out_.twist_sd_rad[k] = std::sqrt(std::max(0.0, covariance(at, at)));
      MountingResult& m = mountings_[k];
      m.m_cs = turned(m.m_cs, turns[k]);
      m.twist_rad += turns[k](2);
      m.twist_reference = reference_;
      m.angles(0) = (std::isnan(m.angles(0)) ? 0.0 : m.angles(0)) + turns[k](2);
    }
    batch_ = batch_at_(candidates_, mountings_, nominal_, square_corner_);
  }

  void restore(std::span<const std::size_t> mountings) override {
    for (const std::size_t k : mountings) {
      MountingResult& m = mountings_[k];
      const StartFrame& start = start_[k];
      m.m_cs = start.m_cs;
      m.twist_rad = start.twist_rad;
      m.twist_reference = start.twist_reference;
      m.angles(0) = start.twist_angle;
      out_.twist_sd_rad[k] = 0.0;
    }
    batch_ = batch_at_(candidates_, mountings_, nominal_, square_corner_);
  }

  void hold(std::span<const TurnParameter> parameters, std::size_t twist, const Eigen::MatrixXd& information,
            const TwistHeld& why) override {
    MountingResult& m = mountings_[parameters[twist].mounting];
    out_.held.push_back(parameters[twist].mounting);
    m.twist_reference = reference_;
    m.angles(0) = 0.0;
    m.angles_sd(0) = 0.0;   // held
    // A held twist leaks into the tilts the stage estimated with it: by how much, for a twist of
    // the tolerance, is the regression of the tilts on the twist in the information (the other
    // parameters free). It widens the angles' sd as the batch's refit widens the terms'.
    const auto j = static_cast<Eigen::Index>(twist);
    std::vector<Eigen::Index> others;
    for (Eigen::Index r = 0; r < information.rows(); ++r)
      if (r != j) others.push_back(r);
    const Eigen::MatrixXd i_oo = information(others, others);
    const Eigen::VectorXd shift = -i_oo.ldlt().solve(information(others, j)) * options_.mounting_tolerance_rad;
    for (std::size_t r = 0; r < others.size(); ++r) {
      const TurnParameter& tilt = parameters[static_cast<std::size_t>(others[r])];
      if (tilt.mounting != parameters[twist].mounting || !std::isfinite(shift(static_cast<Eigen::Index>(r)))) continue;
      const int angle = angle_of_turn(tilt.axis);
      m.angles_sd(angle) = std::hypot(m.angles_sd(angle), shift(static_cast<Eigen::Index>(r)));
      m.angles_held_sd(angle) = std::abs(shift(static_cast<Eigen::Index>(r)));
    }
    out_.notes.push_back(held_twist_note(m.mounting, reference_, why, options_.mounting_tolerance_rad));
  }

 private:
  /// What turn() changes of a mounting, as the search found it.
  struct StartFrame {
    frames::Dcm m_cs;
    double twist_rad = 0.0;
    std::string twist_reference;
    double twist_angle = 0.0;
  };

  StackedRegression& batch_;
  std::vector<MountingResult>& mountings_;
  const BatchRegression& batch_at_;
  std::span<const Term> candidates_;
  std::optional<double> square_corner_;
  const dataset::Dataset& data_;
  const PipelineOptions& options_;
  std::function<double(double)> below_record_;
  RelativeTwists& out_;
  std::string reference_;
  std::vector<Eigen::Vector3d> nominal_;
  ident::UlsOptions uls_;
  std::vector<StartFrame> start_;
};

}  // namespace

RelativeTwists relative_twists(StackedRegression batch, std::vector<MountingResult> mountings, const BatchRegression& batch_at,
                               std::span<const Term> candidates, std::optional<double> square_corner,
                               const dataset::Dataset& data, const PipelineOptions& options,
                               const std::function<double(double)>& below_record) {
  RelativeTwists out;
  out.twist_sd_rad.assign(mountings.size(), 0.0);
  const auto finish = [&]() {
    out.batch = std::move(batch);
    out.mountings = std::move(mountings);
    return std::move(out);
  };
  if (!options.batch_relative_twist || data.sensor != dataset::SensorKind::Accelerometer || !uses_cross_axes(candidates))
    return finish();
  const auto reference_at =
      std::find_if(mountings.begin(), mountings.end(), [](const MountingResult& m) { return m.aligned; });
  if (reference_at == mountings.end()) return finish();
  const auto reference_index = static_cast<std::size_t>(reference_at - mountings.begin());
  std::vector<std::size_t> turning;
  std::vector<std::array<bool, 2>> tilts_determined(mountings.size());
  for (std::size_t k = 0; k < mountings.size(); ++k) {
    if (mountings[k].aligned && k != reference_index) turning.push_back(k);
    tilts_determined[k] = {mountings[k].excitation.determined[1], mountings[k].excitation.determined[2]};
  }
  RowTurns rows(batch, mountings, batch_at, candidates, square_corner, data, options, below_record, out, reference_at->mounting);
  out.estimated = search_turns(rows, std::move(turning), tilts_determined, options.mounting_tolerance_rad);
  for (std::size_t k : out.estimated) {
    // The tilts as algorithm 1 reads them: of n_i alone (the twist is angles(0)).
    MountingResult& m = mountings[k];
    const Eigen::Vector3d tilts = rotation_vector(misalignment_from_sensitivities(m.m_cs.row(0).transpose(), frames::Dcm::Identity()));
    m.angles(1) = tilts(1);
    m.angles(2) = tilts(2);
  }
  return finish();
}

}  // namespace inertia::procedure
