#pragma once
// The model the online estimator fits (online_estimator.hpp): its terms (a model file's, or the
// sensor kind's default), the basis of case-frame monomials that holds them, their external-frame
// sensitivities and the structure table's candidates (live_basis.hpp), the solver over that
// basis (live_solver.hpp) and the squares' corner, the model file's or a grid to search. Built
// once per estimator from its arguments; every other part of the estimator reads it.
#include <Eigen/Dense>

#include <memory>
#include <optional>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/online/corner_grid.hpp"
#include "analyzer/online/information.hpp"
#include "analyzer/online/live_basis.hpp"
#include "analyzer/online/live_solver.hpp"
#include "analyzer/online/online_estimator.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace inertia::online {

struct LiveModel {
  /// InputError when a term needs what the live stream cannot provide (OnlineEstimator's constructor).
  LiveModel(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model_file, double t_ref,
            const OnlineOptions& options);

  /// OnlineEstimator::default_terms.
  static std::vector<ident::Term> default_terms(dataset::SensorKind sensor, bool temperature);

  dataset::SensorKind sensor;
  double t_ref;
  OnlineOptions options;
  std::vector<ident::Term> model_terms;
  frames::Dcm model_m_cs = frames::Dcm::Identity();
  std::unique_ptr<LiveBasis> basis;
  std::unique_ptr<LiveSolver> solver;
  std::vector<Eigen::Index> frame_free_model;   // the model's frame-free terms: what is fitted with no mounting aligned
  std::vector<Eigen::Index> model, candidates;
  CornerGrid grid;   // the squares' corner: the model's, or the nodes it is interpolated on
  bool rational = false;
  Eigen::Index model_max_lag = 0;
  /// The default terms (no model file): a search, whose terms the data must show significant;
  /// a model file's terms are fitted as given.
  bool searched = false;

  /// Statistics of no rows in the basis.
  [[nodiscard]] Information empty_information() const {
    return Information(basis->base_size(), basis->filtered_size(), grid.nodes().size());
  }
};

}  // namespace inertia::online
