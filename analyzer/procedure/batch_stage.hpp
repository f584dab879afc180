#pragma once
// Blocks 7-11: every case's references mapped to F_S with the M_E^S its mounting gives, the
// cases concatenated (optionally weighted, section 3.4) and whitened, the aligned mountings'
// relative twists, the batch model fixed or selected (section 2.7.2), and the inference after
// selection with what the searched and the held angles add to it.
#include <string_view>

#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// The batch model of `data` on the mountings of `mounted` (blocks 5-6: its mountings, the cases'
/// M_E^S, M_C^S and the notes so far), which it returns completed.
PipelineResult identify_batch(PipelineResult mounted, const dataset::Dataset& data, const PipelineOptions& options,
                              std::string_view dataset_label);

}  // namespace inertia::procedure
