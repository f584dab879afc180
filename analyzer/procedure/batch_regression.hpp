#pragma once
// The batch's stacked problem (blocks 7-9): every case's references mapped to F_S with the M_E^S
// its mounting gives, weighted, and, for the searches and the held angles, the same problem
// rebuilt with the mountings turned or the squares' corner moved.
#include <Eigen/Dense>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "analyzer/procedure/placement.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// Sets each case's M_E^S = M_C^S M_E^C, with its mounting's M_C^S turned by `turns` (turned(),
/// one per mounting; zero: as estimated).
void set_case_frames(const dataset::Dataset& data, const std::vector<MountingResult>& mountings,
                     const std::vector<Eigen::Vector3d>& turns, std::vector<CaseOutcome>& cases);

/// Every case of `data` to stack, with its M_E^S (`cases`) and its weight.
std::vector<StackInput> batch_inputs(const dataset::Dataset& data, const PipelineOptions& options,
                                     const std::vector<CaseOutcome>& cases);

/// The batch's whitened regression of some terms, rebuilt with each mounting turned and the
/// squares through a corner: what the searched parameters' derivatives, the relative twists and
/// the held angles' refits need.
class BatchRegression {
 public:
  BatchRegression(const dataset::Dataset& data, const PipelineOptions& options, std::string_view label,
                  Eigen::Index first_row, ArWhitener whitener)
      : data_(data), options_(options), label_(label), first_row_(first_row), whitener_(std::move(whitener)) {}

  [[nodiscard]] StackedRegression operator()(std::span<const ident::Term> terms, const std::vector<MountingResult>& mountings,
                                             const std::vector<Eigen::Vector3d>& turns, std::optional<double> corner) const;
  /// The same regression before its whitener (prediction_derivative whitens what it needs of it),
  /// of the cases `only` (empty: every case).
  [[nodiscard]] StackedRegression unwhitened(std::span<const ident::Term> terms, const std::vector<MountingResult>& mountings,
                                             const std::vector<Eigen::Vector3d>& turns, std::optional<double> corner,
                                             std::span<const std::size_t> only = {}) const;
  /// procedure::placement_columns over this regression's rows.
  [[nodiscard]] Eigen::MatrixXd placement_columns(std::span<const ident::Term> terms, const Eigen::VectorXd& theta,
                                                  const std::vector<MountingResult>& mountings,
                                                  const std::vector<Eigen::Vector3d>& turns, std::optional<double> corner,
                                                  std::span<const StatedPlacement> placements) const;
  [[nodiscard]] const ArWhitener& whitener() const { return whitener_; }

 private:
  const dataset::Dataset& data_;
  const PipelineOptions& options_;
  std::string label_;
  Eigen::Index first_row_;
  ArWhitener whitener_;
};

}  // namespace inertia::procedure
