#include "analyzer/procedure/mountings.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

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
  m.known_bias = known_bias.value_or(0.0);
  for (const std::size_t index : indices) {
    const dataset::CaseData& c = data.cases.at(index);
    m.cases.push_back(&c);
    m.kind.add_case(c.kind);
    m.weights.push_back(case_weight(options, c));
  }
  return m;
}

std::vector<StackInput> stack_inputs(const MountingCases& m, const frames::Dcm& m_cs) {
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < m.cases.size(); ++i) {
    const dataset::CaseData& c = *m.cases[i];
    inputs.push_back({m.indices[i], &c, m_cs * c.m_ec, m.weights[i], {c.m_ec, m.known_bias}});
  }
  return inputs;
}

Eigen::Matrix4d case_input_gram(const dataset::CaseData& c, dataset::SensorKind sensor) {
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  if (gyro && !c.w_e) return Eigen::Matrix4d::Zero();
  const auto& x = gyro ? *c.w_e : c.a_e;
  // [x 1]'[x 1] in F_E, turned into the case frame: T G T' with T = diag(M_E^C, 1).
  Eigen::Matrix4d g;
  g.topLeftCorner<3, 3>() = x.transpose() * x;
  g.topRightCorner<3, 1>() = x.colwise().sum().transpose();
  g.bottomLeftCorner<1, 3>() = g.topRightCorner<3, 1>().transpose();
  g(3, 3) = static_cast<double>(x.rows());
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topLeftCorner<3, 3>() = c.m_ec;
  return t * g * t.transpose();
}

}  // namespace inertia::procedure
