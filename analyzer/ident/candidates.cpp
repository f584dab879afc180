#include "analyzer/ident/candidates.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "common/input_error.hpp"

namespace inertia::ident {

namespace {

Factor plain(Variable v, int lag = 0, int power = 1) { return Factor{v, lag, FactorFunction::Plain, power}; }
Factor abs_of(Variable v, int lag = 0) { return Factor{v, lag, FactorFunction::Abs, 1}; }
Factor sign_of(Variable v, int lag = 0) { return Factor{v, lag, FactorFunction::Sign, 1}; }

// u_ES (eq. 1) or u_S (eq. 3) at lag l.
std::vector<Term> accelerometer_inputs(ModelFrame frame, int l, bool sign_abs) {
  using V = Variable;
  std::vector<std::vector<Factor>> u;
  if (frame == ModelFrame::ExternalAndSensor) {
    u.push_back({plain(V::Ax, l)});
    u.push_back({plain(V::Ay, l)});
    u.push_back({plain(V::Az, l)});
  } else {
    u.push_back({plain(V::Ai, l)});
  }
  u.push_back({plain(V::Ai, l, 2)});
  u.push_back({plain(V::Ap, l, 2)});
  u.push_back({plain(V::Ao, l, 2)});
  u.push_back({plain(V::Ai, l), plain(V::Ap, l)});
  u.push_back({plain(V::Ai, l), plain(V::Ao, l)});
  u.push_back({plain(V::Ap, l), plain(V::Ao, l)});
  if (sign_abs) {
    u.push_back({sign_of(V::Ai, l)});
    u.push_back({abs_of(V::Ai, l)});
    u.push_back({plain(V::Ai, l), abs_of(V::Ai, l)});
  }
  std::vector<Term> terms;
  for (auto& factors : u) terms.push_back(Term::from_factors(std::move(factors)));
  return terms;
}

}  // namespace

bool CandidateOptions::is_valid(std::string* why) const {
  if (r < 0 || r > kMaxLag) {
    if (why) *why = fmt::format("model order r = {} is outside 0..{}", r, kMaxLag);
    return false;
  }
  return true;
}

std::vector<Term> candidate_terms(dataset::SensorKind sensor, ModelFrame frame, const CandidateOptions& options) {
  if (std::string why; !options.is_valid(&why)) throw InputError("candidate options: " + why);
  using V = Variable;
  std::vector<Term> terms;
  const auto add = [&](std::vector<Factor> factors) { terms.push_back(Term::from_factors(std::move(factors))); };
  if (options.include_bias) terms.emplace_back();

  if (sensor == dataset::SensorKind::Accelerometer) {
    for (int l = 0; l <= options.r; ++l) {
      for (Term& t : accelerometer_inputs(frame, l, options.include_sign_abs)) terms.push_back(std::move(t));
    }
  } else {
    if (frame == ModelFrame::ExternalAndSensor) {
      add({plain(V::Wx)});
      add({plain(V::Wy)});
      add({plain(V::Wz)});
    } else {
      add({plain(V::Wi)});
    }
    add({plain(V::Wi), plain(V::Y)});
    for (int l = 0; l <= options.r; ++l) {
      add({plain(V::Ai, l)});
      add({plain(V::Ap, l)});
      add({plain(V::Ao, l)});
    }
  }
  if (options.include_output_lags) {
    for (int l = 1; l <= options.r; ++l) add({plain(V::Y, l)});
  }
  if (options.include_noise_terms) {
    for (int l = 1; l <= options.r; ++l) add({plain(V::E, l)});
  }
  if (options.include_temperature) {
    add({plain(V::T)});
    if (sensor == dataset::SensorKind::Accelerometer) {
      add({plain(V::Ai), plain(V::T)});
    } else {
      add({plain(V::T, 1)});
      add({plain(V::T), plain(V::Y)});
    }
  }

  for (const std::string& text : options.exclude) {
    const Term excluded = parse_term(text);
    const auto it = std::find(terms.begin(), terms.end(), excluded);
    if (it == terms.end()) {
      throw InputError(fmt::format("excluded term '{}' is not among the {} {} candidates", text, terms.size(),
                                   dataset::to_string(sensor)));
    }
    terms.erase(it);
  }
  return terms;
}

std::vector<Term> to_sensor_frame(const std::vector<Term>& terms) {
  std::vector<Term> out;
  out.reserve(terms.size());
  for (const Term& term : terms) {
    std::vector<Factor> factors = term.factors();
    for (Factor& f : factors) {
      if (f.variable == Variable::Ax || f.variable == Variable::Ay || f.variable == Variable::Az) f.variable = Variable::Ai;
      if (f.variable == Variable::Wx || f.variable == Variable::Wy || f.variable == Variable::Wz) f.variable = Variable::Wi;
    }
    Term mapped = factors.empty() ? Term{} : Term::from_factors(std::move(factors));
    if (std::find(out.begin(), out.end(), mapped) == out.end()) out.push_back(std::move(mapped));
  }
  return out;
}

}  // namespace inertia::ident
