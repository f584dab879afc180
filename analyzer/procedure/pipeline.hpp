#pragma once
// The data-analysis half of the paper's Fig. 1:
//   blocks 5-6   per mounting, algorithm 2: model selection with misalignment estimation (or a
//                fixed model, for the paper's "simple" comparison), giving M_E^S of every case;
//   blocks 7-8   every case's references mapped to F_S with its M_E^S;
//   block 9      the cases concatenated (optionally weighted, section 3.4);
//   block 10/11  batch identification fixed on a model, or by selection (section 2.7.2).
//
// Each block is a stage of its own, with its input and output as values: plan_validation.hpp
// (what the plan can determine), mountings.hpp (which cases share a mounting), mounting_stage.hpp
// (blocks 5-6), batch_stage.hpp (blocks 7-11), and beneath them whitened_problem.hpp (the
// regression, its noise model and the squares' corner), identifiable_fit.hpp, relative_twists.hpp
// and post_selection_inference.hpp. run_pipeline composes them.
#include <string_view>

#include "analyzer/procedure/mounting_stage.hpp"
#include "analyzer/procedure/mountings.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "analyzer/procedure/plan_validation.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// Runs blocks 5-11 on `data`: identify_batch(run_mounting_stages(...)). Throws InputError for bad
/// input (missing columns, bad options) and std::runtime_error when nothing can be identified (the
/// message names the terms involved).
PipelineResult run_pipeline(const dataset::Dataset& data, const PipelineOptions& options,
                            std::string_view dataset_label);

/// Blocks 5-6 alone: the plan checked, every mounting's algorithm 2, each case's M_E^S. They read
/// no batch option (options.batch, batch_square_highpass), so runs that differ only in the batch
/// model can share them and call identify_batch (batch_stage.hpp) on each.
PipelineResult run_mounting_stages(const dataset::Dataset& data, const PipelineOptions& options,
                                   std::string_view dataset_label);

}  // namespace inertia::procedure
