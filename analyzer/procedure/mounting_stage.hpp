#pragma once
// Blocks 5-6 for one mounting, algorithm 2: the terms the mounting rules and its excitation
// leave in, the misalignment by a fixed point on algorithm 1, the selection of the model with
// the misalignment re-estimated for each candidate, the honest inference on the selected model,
// and the tilt of n_i it keeps folded back into M_C^S.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// Blocks 5-6 for the mounting `mounting` of the cases `cases` (dataset indices).
/// `known_bias`: a bias (output unit) estimated by another mounting (mounting_rules.hpp,
/// takes_bias), subtracted from the output first; `known_bias_sd` its sd, which the angles' sd
/// carry (handed_bias_covariance).
MountingResult estimate_mounting(const dataset::Dataset& data, const std::vector<std::size_t>& cases,
                                 const std::string& mounting, const PipelineOptions& options,
                                 std::string_view dataset_label, std::optional<double> known_bias = std::nullopt,
                                 double known_bias_sd = 0.0);

}  // namespace inertia::procedure
