#include "analyzer/procedure/pipeline.hpp"

#include <utility>

#include "analyzer/procedure/batch_stage.hpp"
#include "analyzer/procedure/mounting_rules.hpp"
#include "analyzer/procedure/mounting_stage.hpp"
#include "analyzer/procedure/mountings.hpp"
#include "analyzer/procedure/plan_validation.hpp"

namespace inertia::procedure {

PipelineResult run_pipeline(const dataset::Dataset& data, const PipelineOptions& options,
                            std::string_view dataset_label) {
  return identify_batch(run_mounting_stages(data, options, dataset_label), data, options, dataset_label);
}

PipelineResult run_mounting_stages(const dataset::Dataset& data, const PipelineOptions& options,
                                   std::string_view dataset_label) {
  check_plan(data, options, dataset_label);
  PipelineResult result;
  result.cases.resize(data.cases.size());

  // Blocks 5-6, in the order and with the bias the mounting rules give (mounting_rules.hpp).
  const MountingGroups groups = mountings_of(data, &result.notes);
  const std::vector<MountingKind> kinds = mounting_kinds(data, groups);
  std::optional<double> bias;
  double bias_sd = 0.0;
  for (const std::size_t g : mounting_order(kinds)) {
    const auto& [mounting, cases] = groups[g];
    const bool takes = takes_bias(kinds[g], options.ieee_1293);
    MountingResult m = estimate_mounting(data, cases, mounting, options, dataset_label, takes ? bias : std::nullopt,
                                         takes ? bias_sd : 0.0);
    if (!bias && hands_on_bias(kinds[g])) {
      for (std::size_t j = 0; j < m.s_fit.labels.size(); ++j) {
        if (m.s_fit.labels[j] == "1") bias = m.s_fit.theta(static_cast<Eigen::Index>(j));
      }
      if (bias) bias_sd = m.bias_sd.value_or(0.0);
    }
    for (std::size_t index : cases) {
      result.cases[index].case_index = index;
      result.cases[index].m_es = m.m_cs * data.cases[index].m_ec;   // M_E^S = M_C^S M_E^C
    }
    result.mountings.push_back(std::move(m));
  }
  result.m_cs = result.mountings.front().m_cs;
  for (const MountingResult& m : result.mountings) {
    if (m.aligned) {
      result.m_cs = m.m_cs;   // the model file's M_C^S: the first mounting the data aligned
      break;
    }
  }
  return result;
}

}  // namespace inertia::procedure
