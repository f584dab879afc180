#include "analyzer/diagnose/candidate_library.hpp"

namespace inertia::diagnose {

std::vector<ident::Term> candidate_library(dataset::SensorKind sensor, const LibraryOptions& options) {
  std::vector<const char*> names;
  if (sensor == dataset::SensorKind::Accelerometer) {
    names = {"1", "a_i", "a_p", "a_o", "a_i^2", "a_p^2", "a_o^2", "a_i*a_p", "a_i*a_o", "a_p*a_o",
             "abs(a_i)", "a_i*abs(a_i)", "sign(a_i)"};
    if (options.temperature) names.insert(names.end(), {"T", "a_i*T"});
    if (options.dynamics) names.insert(names.end(), {"a_i[k-1]", "a_i^2[k-1]", "a_p^2[k-1]", "a_o^2[k-1]", "y[k-1]"});
  } else {
    names = {"1", "w_i", "w_p", "w_o", "w_i^2", "w_i*abs(w_i)", "a_i", "a_p", "a_o", "y*w_i"};
    if (options.temperature) names.insert(names.end(), {"T", "w_i*T", "y*T"});
    if (options.dynamics) {
      names.insert(names.end(), {"w_i[k-1]", "a_i[k-1]", "y[k-1]"});
      if (options.temperature) names.push_back("T[k-1]");
    }
  }
  std::vector<ident::Term> terms;
  terms.reserve(names.size());
  for (const char* n : names) terms.push_back(ident::parse_term(n));
  return terms;
}

bool dataset_supports(const dataset::Dataset& data, const ident::Term& term) {
  for (const dataset::CaseData& c : data.cases) {
    for (ident::Variable v : term.variables()) {
      using ident::Variable;
      const bool rate = v == Variable::Wi || v == Variable::Wp || v == Variable::Wo || v == Variable::Wx ||
                        v == Variable::Wy || v == Variable::Wz;
      if (rate && !c.w_e) return false;
      if (v == Variable::T && !c.temp) return false;
      if (v == Variable::E) return false;   // residual lags describe noise, not a missing effect
    }
  }
  return true;
}

}  // namespace inertia::diagnose
