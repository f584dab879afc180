#pragma once
// What a plan can determine, said before and after the fit: input checks with advice (bad input
// is an InputError that says what the plan needs), the terms offered to the selection, and why a
// candidate the plan does not determine is left out.
#include <Eigen/Dense>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/ident/candidates.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// InputError for a dataset the procedure cannot run on: no cases, a weight for a case it does
/// not have, a gyroscope case without rates, or a plan whose sensitive input does not vary (the
/// scale factor cannot be told from the bias).
void check_plan(const dataset::Dataset& data, const PipelineOptions& options, std::string_view dataset_label);

/// InputError naming a weight whose case the dataset does not have.
void check_case_weights(const dataset::Dataset& data, const PipelineOptions& options);

/// The terms `choice` offers in `frame`: the candidates (with the temperature terms when the
/// fixture temperature varies enough, PipelineOptions::temperature_when_measured), or its fixed
/// model (`what` names it in the error when it is empty).
std::vector<ident::Term> offered_terms(const ModelChoice& choice, ident::ModelFrame frame, const dataset::Dataset& data,
                                       const PipelineOptions& options, const char* what);

/// The note for the user when the temperature terms are not offered because the fixture
/// temperature does not vary enough; none otherwise.
std::optional<std::string> temperature_note(const dataset::Dataset& data, const PipelineOptions& options);

/// The columns of `s` that are not in `ranking` (identifiable_ranking), each with why: a zero
/// column needs excitation of its variables; otherwise it is (nearly) a combination of ranked
/// columns, named by their shares.
std::vector<UndeterminedTerm> undetermined_columns(const StackedRegression& s, const std::vector<Eigen::Index>& ranking);

}  // namespace inertia::procedure
