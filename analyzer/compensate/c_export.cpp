#include "analyzer/compensate/c_export.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <ostream>

#include "analyzer/compensate/c_text.hpp"
#include "analyzer/compensate/joint_inverse.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "common/input_error.hpp"

namespace inertia::compensate {

using namespace c_text;

using ident::FactorFunction;
using ident::Variable;

CSource generate_c(const model::ModelFile& model, const std::string& prefix, CPrecision precision,
                   const CompensationOptions& options) {
  if (!is_identifier(prefix)) throw InputError(fmt::format("--prefix '{}' is not a C identifier", prefix));
  const InverseModel inverse(model);
  const Variable sensed = inverse.sensed();
  const bool reads_t = inverse.known_inputs().test(static_cast<std::size_t>(Variable::T));
  const COneOutput api{
      fmt::format("{} '{}'", dataset::to_string(model.sensor), model.name.empty() ? "(unnamed)" : model.name),
      sensed == Variable::Ai ? "m/s^2" : "rad/s",
      !reads_t       ? std::string()
      : model.t_ref ? fmt::format("; T = temp - {} degC", *model.t_ref)
                    : std::string("; T = temp - the characterization's t_ref, which the model does not state")};
  const JointCSource joint = generate_joint_c(inverse.as_joint(), {model.name}, {ident::variable_name(sensed)}, prefix, precision,
                                              model.sample_period_s, options, &api);
  CSource out{joint.header, joint.source, {}};
  for (const auto& [output, variable] : joint.inputs) out.inputs.push_back(variable);
  return out;
}

void write_test_vectors(std::ostream& out, const model::ModelFile& model, const std::vector<ident::Variable>& inputs,
                        const ident::SignalSet& signals, double sample_period_s, const CompensationOptions& options) {
  const InverseModel inverse(model);
  const CompensatedSignal r = inverse.compensate(signals, sample_period_s, options);
  out << "y";
  for (Variable v : inputs) out << ',' << ident::variable_name(v);
  out << ",value,u_coefficients,u_noise,flag\n";
  for (Eigen::Index k = 0; k < signals.size(); ++k) {
    fmt::print(out, "{}", signals.get(Variable::Y)(k));
    for (Variable v : inputs) fmt::print(out, ",{}", signals.get(v)(k));
    if (k < r.first_row) {
      fmt::print(out, ",nan,nan,nan,3\n");
      continue;
    }
    const Eigen::Index i = k - r.first_row;
    fmt::print(out, ",{},{},{},{}\n", r.value(i), r.u_coefficients(i), r.u_noise(i), static_cast<int>(r.flag[std::size_t(i)]));
  }
}

}  // namespace inertia::compensate
