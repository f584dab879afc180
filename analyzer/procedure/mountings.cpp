#include "analyzer/procedure/mountings.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "common/parallel.hpp"

namespace inertia::procedure {

MountingGroups group_mountings(const std::vector<MountingKey>& cases, dataset::SensorKind sensor,
                               std::vector<std::string>* notes) {
  const auto note = [&](std::string text) {
    if (notes != nullptr) notes->push_back(std::move(text));
  };
  MountingGroups groups;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string& label = cases[i].label.empty() ? cases[i].name : cases[i].label;
    auto it = std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == label; });
    if (it == groups.end()) {
      groups.emplace_back(label, std::vector<std::size_t>{i});
    } else {
      it->second.push_back(i);
    }
  }
  if (sensor == dataset::SensorKind::Gyroscope) {
    if (groups.size() > 1) {
      note("gyroscope: one M_C^S for every case, from the rate sensitivities of all cases together (paper section 2.2: "
           "M_E^C of each case must be known accurately); mounting labels are not used");
    }
    std::vector<std::size_t> all(cases.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
    return {{"all cases", all}};
  }
  const bool labelled = std::any_of(cases.begin(), cases.end(), [](const MountingKey& c) { return !c.label.empty(); });
  std::vector<std::size_t> poses;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    if (cases[i].kind == CaseKind::Static || cases[i].kind == CaseKind::Thermal) poses.push_back(i);
  }
  if (!labelled && poses.size() >= 2) {
    std::erase_if(groups, [&](const auto& g) { return std::find(poses.begin(), poses.end(), g.second.front()) != poses.end(); });
    groups.insert(groups.begin(), {"poses", poses});
    std::vector<std::string> names;
    for (std::size_t i : poses) names.push_back(cases[i].name);
    note(fmt::format("inferred: the {} static poses ({}) share one mounting 'poses' (the sensor stays in its fixture, "
                     "which is turned between them); give each case a `mounting` label in dataset.toml to say otherwise",
                     poses.size(), fmt::join(names, ", ")));
  }
  return groups;
}

MountingGroups mountings_of(const dataset::Dataset& data, std::vector<std::string>* notes) {
  std::vector<MountingKey> keys;
  for (const dataset::CaseData& c : data.cases) keys.push_back({c.plan_case(), c.mounting, c.kind});
  return group_mountings(keys, data.sensor, notes);
}

std::vector<MountingKind> mounting_kinds(const dataset::Dataset& data, const MountingGroups& groups) {
  std::vector<MountingKind> kinds(groups.size());
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (std::size_t index : groups[g].second) kinds[g].add_case(data.cases[index].kind);
  return kinds;
}

double case_weight(const PipelineOptions& options, const dataset::CaseData& c) {
  for (const auto& [key, weight] : options.case_weights)
    if (key == c.plan_case()) return weight;
  return 1.0;
}

MountingCases mounting_cases(const dataset::Dataset& data, const std::vector<std::size_t>& indices,
                             const PipelineOptions& options, std::optional<double> known_bias) {
  MountingCases m;
  m.indices = indices;
  m.cases.resize(indices.size());
  parallel::for_each_index(static_cast<long>(indices.size()), [&](long i) {
    dataset::CaseData& c = m.cases[static_cast<std::size_t>(i)];
    c = data.cases.at(indices[static_cast<std::size_t>(i)]);
    c.a_e = c.a_e * c.m_ec.transpose();   // rows: (M_E^C a_E)^T
    if (c.w_e) *c.w_e = *c.w_e * c.m_ec.transpose();
    c.m_ec = frames::Dcm::Identity();
    if (known_bias) c.y.array() -= *known_bias;
  });
  for (const dataset::CaseData& c : m.cases) {
    m.kind.add_case(c.kind);
    m.weights.push_back(case_weight(options, c));
  }
  return m;
}

std::vector<StackInput> stack_inputs(const MountingCases& m, const frames::Dcm& m_cs) {
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < m.cases.size(); ++i) inputs.push_back({m.indices[i], &m.cases[i], m_cs, m.weights[i]});
  return inputs;
}

}  // namespace inertia::procedure
