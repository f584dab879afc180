#include "analyzer/procedure/relative_twists.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "analyzer/procedure/identifiable_fit.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/post_selection_inference.hpp"
#include "common/units.hpp"

namespace inertia::procedure {
namespace {

using ident::Term;

/// One Gauss-Newton step for parameters the columns of the fitted, whitened stack `s` are built
/// with (variable projection: the terms re-fitted at every value). `derivatives`: the fitted
/// prediction's derivative per parameter (prediction_derivative). With J~ the derivatives with
/// the fit's columns projected out, the step is (J~'J~)^-1 J~'r; `information` gets J~'J~ /
/// sigma^2, the parameters' information with the terms free.
Eigen::VectorXd gauss_newton_step(const StackedRegression& s, const ident::UlsResult& fit, const Eigen::MatrixXd& derivatives,
                                  Eigen::MatrixXd& information) {
  Eigen::MatrixXd x(s.phi.rows(), fit.process_terms);
  for (Eigen::Index j = 0; j < x.cols(); ++j) {
    const auto at = std::find(s.labels.begin(), s.labels.end(), fit.labels[std::size_t(j)]);
    x.col(j) = s.phi.col(at - s.labels.begin());
  }
  const Eigen::LDLT<Eigen::MatrixXd> gram(x.transpose() * x);
  const Eigen::MatrixXd projected = derivatives - x * gram.solve(x.transpose() * derivatives);
  const Eigen::MatrixXd jj = projected.transpose() * projected;
  information = jj / fit.residual_variance;
  return jj.ldlt().solve(projected.transpose() * fit.residuals);
}

}  // namespace

RelativeTwists relative_twists(StackedRegression batch, std::vector<MountingResult> mountings, const BatchRegression& batch_at,
                               std::span<const Term> candidates, std::optional<double> square_corner,
                               const dataset::Dataset& data, const PipelineOptions& options) {
  RelativeTwists out;
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
  const std::string reference = reference_at->mounting;
  std::vector<std::size_t> turning;
  for (std::size_t k = 0; k < mountings.size(); ++k)
    if (mountings[k].aligned && k != reference_index) turning.push_back(k);
  const std::vector<Eigen::Vector3d> nominal(mountings.size(), Eigen::Vector3d::Zero());
  ident::UlsOptions uls = options.selection.uls;
  uls.noise_lags = 0;
  for (int iteration = 0; iteration < kTurnMaxSteps && !turning.empty(); ++iteration) {
    struct Parameter {
      std::size_t mounting;
      int axis;   // of turned(): 0, 1 tilts, 2 twist
    };
    std::vector<Parameter> parameters;
    for (std::size_t k : turning) {
      for (int axis = 0; axis < 2; ++axis)
        if (mountings[k].excitation.determined[static_cast<std::size_t>(axis) + 1]) parameters.push_back({k, axis});
      parameters.push_back({k, 2});
    }
    std::vector<Eigen::Index> usable = identifiable_ranking(batch, data.sensor, options.selection.err);
    std::vector<std::string> dropped;
    const ident::UlsResult fit = fit_identifiable(batch, data.sensor, usable, uls, dropped);
    Eigen::MatrixXd derivatives(batch.phi.rows(), static_cast<Eigen::Index>(parameters.size()));
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      derivatives.col(static_cast<Eigen::Index>(i)) =
          prediction_derivative(fit, 1e-4, batch_at.whitener(), [&](std::span<const Term> terms, double moved) {
            std::vector<Eigen::Vector3d> turns = nominal;
            turns[parameters[i].mounting](parameters[i].axis) = moved;
            return batch_at.unwhitened(terms, mountings, turns, square_corner);
          });
    }
    Eigen::MatrixXd information;
    const Eigen::VectorXd delta = gauss_newton_step(batch, fit, derivatives, information);
    const Eigen::VectorXd sd = information.ldlt()
                                   .solve(Eigen::MatrixXd::Identity(information.rows(), information.cols()))
                                   .diagonal()
                                   .cwiseMax(0.0)
                                   .cwiseSqrt();
    if (iteration == 0) {
      std::vector<std::size_t> determined;
      for (std::size_t i = 0; i < parameters.size(); ++i) {
        if (parameters[i].axis != 2) continue;
        const double twist_sd = sd(static_cast<Eigen::Index>(i));
        MountingResult& m = mountings[parameters[i].mounting];
        if (std::isfinite(twist_sd) && twist_sd > 0.0 && twist_sd <= options.mounting_tolerance_rad) {
          determined.push_back(parameters[i].mounting);
        } else {
          out.held.push_back(parameters[i].mounting);
          m.twist_reference = reference;
          m.angles(0) = 0.0;
          m.angles_sd(0) = 0.0;   // held
          // A held twist leaks into the tilts the stage estimated with it: by how much, for a twist
          // of the tolerance, is the regression of the tilts on the twist in the information (the
          // other parameters free). It widens the angles' sd as the batch's refit widens the terms'.
          const auto j = static_cast<Eigen::Index>(i);
          std::vector<Eigen::Index> others;
          for (Eigen::Index r = 0; r < information.rows(); ++r)
            if (r != j) others.push_back(r);
          const Eigen::MatrixXd i_oo = information(others, others);
          const Eigen::VectorXd shift = -i_oo.ldlt().solve(information(others, j)) * options.mounting_tolerance_rad;
          for (std::size_t r = 0; r < others.size(); ++r) {
            const Parameter& tilt = parameters[static_cast<std::size_t>(others[r])];
            if (tilt.mounting != parameters[i].mounting || !std::isfinite(shift(static_cast<Eigen::Index>(r)))) continue;
            const int angle = angle_of_turn(tilt.axis);
            m.angles_sd(angle) = std::hypot(m.angles_sd(angle), shift(static_cast<Eigen::Index>(r)));
            m.angles_held_sd(angle) = std::abs(shift(static_cast<Eigen::Index>(r)));
          }
          out.notes.push_back(fmt::format(
              "the twist about n_i of mounting '{}' against '{}' is not determined by this plan (sd {:.2g} deg with its "
              "tilts free, more than the {:.2f} deg mounting tolerance): held at the nominal frame, and what the tolerance "
              "moves is in the sd; more cross-axis excitation (a_p, a_o) in both mountings determines it",
              m.mounting, reference, rad_to_deg(twist_sd), rad_to_deg(options.mounting_tolerance_rad)));
        }
      }
      if (determined.size() < turning.size()) {
        turning = determined;
        continue;   // the step again, without the held twists
      }
    }
    std::vector<Eigen::Vector3d> turns = nominal;
    for (std::size_t i = 0; i < parameters.size(); ++i) turns[parameters[i].mounting](parameters[i].axis) = delta(static_cast<Eigen::Index>(i));
    for (std::size_t k : turning) {
      MountingResult& m = mountings[k];
      m.m_cs = turned(m.m_cs, turns[k]);
      m.twist_rad += turns[k](2);
      m.twist_reference = reference;
      m.angles(0) = (std::isnan(m.angles(0)) ? 0.0 : m.angles(0)) + turns[k](2);
    }
    batch = batch_at(candidates, mountings, nominal, square_corner);
    if ((delta.array().abs() <= kTurnConvergence * sd.array()).all()) break;
  }
  out.estimated = turning;
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
