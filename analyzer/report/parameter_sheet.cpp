#include "analyzer/report/parameter_sheet.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <tuple>

#include <fmt/ranges.h>

#include "analyzer/compensate/static_response.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"

namespace inertia::report {

using Eigen::Index;
using ident::FactorFunction;
using ident::Term;
using ident::Variable;

namespace {

constexpr double kG = kStandardGravity;
constexpr double kDegPerHourPerRadPerSecond = 180.0 / std::numbers::pi * 3600.0;

bool single_factor(const Term& t, Variable v, int power, FactorFunction fn = FactorFunction::Plain) {
  const auto& f = t.factors();
  return f.size() == 1 && f[0].variable == v && f[0].power == power && f[0].function == fn;
}

/// A product of two distinct plain variables, unlagged.
bool product_of(const Term& t, Variable a, Variable b) {
  const auto& f = t.factors();
  if (f.size() != 2 || f[0].power != 1 || f[1].power != 1 || f[0].lag != 0 || f[1].lag != 0) return false;
  return (f[0].variable == a && f[1].variable == b) || (f[0].variable == b && f[1].variable == a);
}

using Predicate = std::function<bool(const Term&)>;
using Function = std::function<double(const Eigen::VectorXd&)>;

struct Definition {
  const char* name;
  const char* symbol;
  std::string unit;
  Predicate traces;        // the model terms the parameter is made of
  Function value;          // in `unit`, from the coefficients
  std::string derivation;
  std::string absent{};    // why no term traces it, where the model's structure says (else: not selected)
};

class SheetBuilder {
 public:
  explicit SheetBuilder(const model::ModelFile& m) : m_(m) {
    const auto n = static_cast<Index>(m.terms.size());
    theta_.resize(n);
    for (Index j = 0; j < n; ++j) theta_(j) = m.terms[static_cast<std::size_t>(j)].coefficient;
    if (m.covariance.rows() == n && n > 0) {
      covariance_ = m.covariance;
    } else {
      covariance_ = Eigen::MatrixXd::Zero(n, n);
      for (Index j = 0; j < n; ++j) covariance_(j, j) = std::pow(m.terms[static_cast<std::size_t>(j)].std.value_or(0.0), 2);
    }
  }

  /// The settled output at inputs `at` (the others 0), with coefficients theta.
  [[nodiscard]] double output(const Eigen::VectorXd& theta, std::initializer_list<std::pair<Variable, double>> at) const {
    compensate::InputValues values{};
    for (const auto& [v, x] : at) values[static_cast<std::size_t>(v)] = x;
    return compensate::static_output(m_, values, {}, theta);
  }

  [[nodiscard]] SheetEntry entry(const Definition& d) const {
    SheetEntry e;
    e.name = d.name;
    e.symbol = d.symbol;
    e.unit = d.unit;
    e.derivation = d.derivation;
    for (const model::ModelTerm& t : m_.terms) {
      if (!t.term.is_noise_term() && d.traces(t.term)) e.terms.push_back(t.term.to_string());
    }
    if (e.terms.empty()) {
      for (const auto& [term, reason] : m_.undetermined) {
        bool matches = false;
        try {
          matches = d.traces(ident::parse_term(term));
        } catch (const InputError&) {
        }
        if (!matches) continue;
        e.status = SheetEntry::Status::Undetermined;
        e.reason = fmt::format("'{}': {}", term, reason);
        return e;
      }
      e.status = SheetEntry::Status::NotSelected;
      if (!d.absent.empty()) {
        e.reason = d.absent;
        return e;
      }
      e.reason = "no term of it was selected: not significant at the selection's level in this plan (a plan that "
                 "excites it more, or a longer one, can resolve it)";
      return e;
    }
    // The delta method: J by central differences, steps a small fraction of each coefficient's sd.
    e.value = d.value(theta_);
    Eigen::VectorXd gradient = Eigen::VectorXd::Zero(theta_.size());
    for (Index j = 0; j < theta_.size(); ++j) {
      const double sd = std::sqrt(std::max(covariance_(j, j), 0.0));
      if (sd == 0.0) continue;
      const double h = 1e-3 * sd;
      Eigen::VectorXd up = theta_, down = theta_;
      up(j) += h;
      down(j) -= h;
      gradient(j) = (d.value(up) - d.value(down)) / (2.0 * h);
    }
    e.expanded_uncertainty = 2.0 * std::sqrt(std::max(0.0, gradient.dot(covariance_ * gradient)));
    if (!std::isfinite(e.value)) {
      e.status = SheetEntry::Status::Undetermined;
      e.reason = "not computable from the model file: it states no characterized range of the input (characterize writes [range])";
    }
    return e;
  }

  [[nodiscard]] const model::ModelFile& model() const { return m_; }

 private:
  const model::ModelFile& m_;
  Eigen::VectorXd theta_;
  Eigen::MatrixXd covariance_;
};

/// A noise parameter: a [noise] term over the static sensitivity, in `scale` x its SI unit.
SheetEntry noise_entry(const model::ModelFile& m, std::size_t slot, double sensitivity, const char* name, const char* symbol,
                       const char* unit, double scale, const char* what) {
  SheetEntry e;
  e.name = name;
  e.symbol = symbol;
  e.unit = unit;
  e.derivation = fmt::format("noise term {} ({}) of the static stretches' Allan deviation over the scale factor", 
                             model::ModelFile::NoiseTerms::kKeys[slot], what);
  if (!m.noise.values[slot]) {
    e.status = SheetEntry::Status::Undetermined;
    e.reason = fmt::format("the noise analysis of the plan's static stretches did not resolve {} (longer or more rests can)",
                           model::ModelFile::NoiseTerms::kKeys[slot]);
    return e;
  }
  e.terms.push_back(std::string("noise ") + model::ModelFile::NoiseTerms::kKeys[slot]);
  e.value = *m.noise.values[slot] / std::abs(sensitivity) * scale;
  e.expanded_uncertainty = 2.0 * m.noise.sd[slot].value_or(std::nan("")) / std::abs(sensitivity) * scale;
  return e;
}

/// The largest deviation of the settled response to the sensed input from its straight line
/// (bias plus K1 x), over the characterized range, as a fraction of full scale (ppm).
double nonlinearity_ppm(const SheetBuilder& b, const Eigen::VectorXd& theta, Variable sensed) {
  const auto& range = b.model().range;
  const auto it = range.find(sensed);
  if (it == range.end()) return std::nan("");
  const double full_scale = std::max(std::abs(it->second.lowest), std::abs(it->second.highest));
  const double k1 = compensate::static_sensitivity(b.model(), sensed, theta);
  const double zero = b.output(theta, {});
  double worst = 0.0;
  for (int i = 0; i <= 40; ++i) {
    const double x = it->second.lowest + (it->second.highest - it->second.lowest) * i / 40.0;
    worst = std::max(worst, std::abs(b.output(theta, {{sensed, x}}) - zero - k1 * x));
  }
  return worst / std::abs(k1 * full_scale) * 1e6;
}

std::vector<Definition> accelerometer_definitions(const SheetBuilder& b) {
  const model::ModelFile& m = b.model();
  const auto k1 = [&m](const Eigen::VectorXd& t) { return compensate::static_sensitivity(m, Variable::Ai, t); };
  // A coefficient's static value (over 1 - the output lags' coefficients) over K1, in ug per g^n.
  const auto coefficient = [&m, k1](const char* term, int order) -> Function {
    const Term wanted = ident::parse_term(term);
    return [&m, k1, wanted, order](const Eigen::VectorXd& t) {
      double c = 0.0, feedback = 0.0;
      for (std::size_t j = 0; j < m.terms.size(); ++j) {
        const Term& mt = m.terms[j].term;
        if (mt == wanted) c = t(static_cast<Index>(j));
        if (mt.factors().size() == 1 && mt.factors()[0].variable == Variable::Y && mt.factors()[0].lag > 0 &&
            mt.factors()[0].power == 1 && mt.factors()[0].function == FactorFunction::Plain)
          feedback += t(static_cast<Index>(j));
      }
      return c / (1.0 - feedback) / k1(t) * std::pow(kG, order - 1) * 1e6;
    };
  };
  const bool high_passed = m.square_highpass_rad_s.has_value();
  std::vector<Definition> d;
  d.push_back({"bias", "K0", "ug", [](const Term& t) { return t.is_bias(); },
               [&b, k1](const Eigen::VectorXd& t) { return b.output(t, {}) / k1(t) / kG * 1e6; },
               "settled output at zero input over K1"});
  d.push_back({"scale factor", "K1", (m.output_unit.empty() ? std::string("output unit") : m.output_unit) + "/g",
               [](const Term& t) { return single_factor(t, Variable::Ai, 1) || t.uses(Variable::Y); },
               [k1](const Eigen::VectorXd& t) { return k1(t) * kG; },
               "the a_i coefficients at every lag over 1 - the output lags' coefficients"});
  d.push_back({"second-order nonlinearity", "K2", "ug/g^2", [](const Term& t) { return single_factor(t, Variable::Ai, 2); },
               coefficient("a_i^2", 2),
               high_passed ? fmt::format("a_i^2 over K1: the gain above eq. 12's corner b = {} rad/s (the squares pass its high pass)",
                                         *m.square_highpass_rad_s)
                           : std::string("a_i^2 over K1")});
  d.push_back({"third-order nonlinearity", "K3", "ug/g^3", [](const Term& t) { return single_factor(t, Variable::Ai, 3); },
               coefficient("a_i^3", 3), "a_i^3 over K1"});
  d.push_back({"odd quadratic", "Koq", "ug/g^2",
               [](const Term& t) {
                 const auto& f = t.factors();
                 return f.size() == 2 && f[0].variable == Variable::Ai && f[1].variable == Variable::Ai &&
                        f[1].function == FactorFunction::Abs;
               },
               coefficient("a_i*abs(a_i)", 2), "a_i*abs(a_i) over K1"});
  d.push_back({"bias asymmetry", "Ks", "ug", [](const Term& t) { return single_factor(t, Variable::Ai, 1, FactorFunction::Sign); },
               coefficient("sign(a_i)", 0), "sign(a_i) over K1: half the bias step between positive and negative inputs"});
  d.push_back({"rectification", "Ka", "ug/g", [](const Term& t) { return single_factor(t, Variable::Ai, 1, FactorFunction::Abs); },
               coefficient("abs(a_i)", 1), "abs(a_i) over K1"});
  d.push_back({"scale-factor nonlinearity over the tested range", "", "ppm of full scale",
               [](const Term& t) {
                 return t.uses(Variable::Ai) && !single_factor(t, Variable::Ai, 1) && !t.uses(Variable::Ap) && !t.uses(Variable::Ao) &&
                        !t.uses(Variable::T);
               },
               [&b](const Eigen::VectorXd& t) { return nonlinearity_ppm(b, t, Variable::Ai); },
               "largest deviation of the settled response to a_i from K0 + K1 a_i over the characterized a_i range, over K1 "
               "times full scale"});
  for (const auto& [axis, symbol] : {std::pair{Variable::Ap, "Kp"}, std::pair{Variable::Ao, "Ko"}}) {
    const std::string name = ident::variable_name(axis);
    d.push_back({axis == Variable::Ap ? "cross-axis sensitivity along p" : "cross-axis sensitivity along o", symbol, "ug/g",
                 [axis](const Term& t) { return single_factor(t, axis, 1); }, coefficient(name.c_str(), 1), name + " over K1"});
  }
  for (const auto& [a, bvar, name, symbol] :
       {std::tuple{Variable::Ai, Variable::Ap, "cross-coupling i-p", "Kip"}, std::tuple{Variable::Ai, Variable::Ao, "cross-coupling i-o", "Kio"},
        std::tuple{Variable::Ap, Variable::Ao, "cross-coupling p-o", "Kpo"}}) {
    const std::string term = std::string(ident::variable_name(a)) + "*" + ident::variable_name(bvar);
    d.push_back({name, symbol, "ug/g^2", [a = a, bvar = bvar](const Term& t) { return product_of(t, a, bvar); },
                 coefficient(term.c_str(), 2), term + " over K1"});
  }
  d.push_back({"vibration rectification coefficient", "VRC", "ug/g^2",
               [high_passed](const Term& t) { return !high_passed && single_factor(t, Variable::Ai, 2); }, coefficient("a_i^2", 2),
               "the static K2: the bias a vibration along i rectifies per g^2 (rms)",
               high_passed ? fmt::format("the model's squares pass eq. 12's high pass (b = {} rad/s), which passes no constant: "
                                         "they rectify no bias by the model's structure",
                                         *m.square_highpass_rad_s)
                           : std::string()});
  d.push_back({"bias temperature coefficient", "", "ug/degC",
               [](const Term& t) { return t.uses(Variable::T) && !t.uses(Variable::Ai) && !t.uses(Variable::Y); },
               [&b, k1](const Eigen::VectorXd& t) {
                 return (b.output(t, {{Variable::T, 1.0}}) - b.output(t, {{Variable::T, -1.0}})) / 2.0 / k1(t) / kG * 1e6;
               },
               "settled output's slope in T at zero input, over K1"});
  d.push_back({"scale-factor temperature coefficient", "", "ppm/degC",
               [](const Term& t) { return t.uses(Variable::T) && (t.uses(Variable::Ai) || t.uses(Variable::Y)); },
               [&b, k1](const Eigen::VectorXd& t) {
                 const auto slope = [&](double temp) {
                   return (b.output(t, {{Variable::Ai, 1.0}, {Variable::T, temp}}) - b.output(t, {{Variable::Ai, -1.0}, {Variable::T, temp}})) / 2.0;
                 };
                 return (slope(1.0) - slope(-1.0)) / 2.0 / k1(t) * 1e6;
               },
               "the settled response's slope in a_i, its change per degC over K1"});
  return d;
}

std::vector<Definition> gyroscope_definitions(const SheetBuilder& b) {
  const model::ModelFile& m = b.model();
  const auto k1 = [&m](const Eigen::VectorXd& t) { return compensate::static_sensitivity(m, Variable::Wi, t); };
  std::vector<Definition> d;
  d.push_back({"bias", "", "deg/h", [](const Term& t) { return t.is_bias(); },
               [&b, k1](const Eigen::VectorXd& t) { return b.output(t, {}) / k1(t) * kDegPerHourPerRadPerSecond; },
               "settled output at zero input over the scale factor"});
  d.push_back({"scale factor", "SF", (m.output_unit.empty() ? std::string("output unit") : m.output_unit) + "/(deg/s)",
               [](const Term& t) { return single_factor(t, Variable::Wi, 1) || t.uses(Variable::Y); },
               [k1](const Eigen::VectorXd& t) { return k1(t) * std::numbers::pi / 180.0; },
               "the w_i coefficients at every lag over 1 - the output lags' coefficients"});
  d.push_back({"scale-factor nonlinearity over the tested range", "", "ppm of full scale",
               [](const Term& t) {
                 return (t.uses(Variable::Wi) && !single_factor(t, Variable::Wi, 1) && !t.uses(Variable::T)) ||
                        (t.is_output_multiplied() && t.uses(Variable::Wi));
               },
               [&b](const Eigen::VectorXd& t) { return nonlinearity_ppm(b, t, Variable::Wi); },
               "largest deviation of the settled response to w_i from its straight line over the characterized w_i range"});
  d.push_back({"scale-factor asymmetry", "", "ppm",
               [](const Term& t) {
                 const auto& f = t.factors();
                 return f.size() == 1 && f[0].variable == Variable::Wi && f[0].function != FactorFunction::Plain;
               },
               [&b](const Eigen::VectorXd& t) {
                 const auto it = b.model().range.find(Variable::Wi);
                 const double w = it == b.model().range.end() ? 1.0 : 0.5 * std::max(std::abs(it->second.lowest), std::abs(it->second.highest));
                 const double zero = b.output(t, {});
                 const double up = (b.output(t, {{Variable::Wi, w}}) - zero) / w, down = (zero - b.output(t, {{Variable::Wi, -w}})) / w;
                 return (up - down) / (0.5 * (up + down)) * 1e6;
               },
               "scale factors for positive and negative rates at half full scale: their difference over their mean"});
  for (const auto& [axis, name] : {std::pair{Variable::Ai, "g-sensitivity along i"}, std::pair{Variable::Ap, "g-sensitivity along p"},
                                   std::pair{Variable::Ao, "g-sensitivity along o"}}) {
    d.push_back({name, "", "(deg/h)/g",
                 [axis = axis](const Term& t) { return t.uses(axis) && !t.uses(Variable::Wi) && t.factors().size() == 1 && t.factors()[0].power == 1; },
                 [&b, k1, axis = axis](const Eigen::VectorXd& t) {
                   return (b.output(t, {{axis, kG}}) - b.output(t, {{axis, -kG}})) / 2.0 / k1(t) * kDegPerHourPerRadPerSecond;
                 },
                 std::string("settled output's odd part in ") + ident::variable_name(axis) + " at 1 g, over the scale factor"});
  }
  d.push_back({"g^2-sensitivity", "", "(deg/h)/g^2",
               [](const Term& t) {
                 return !t.uses(Variable::Wi) && !t.uses(Variable::Y) && !t.uses(Variable::T) && !t.is_bias() &&
                        t.factors().size() >= 1 && (t.factors().size() == 2 || t.factors()[0].power == 2);
               },
               [&b, k1](const Eigen::VectorXd& t) {
                 return (b.output(t, {{Variable::Ai, kG}}) + b.output(t, {{Variable::Ai, -kG}}) - 2.0 * b.output(t, {})) / 2.0 / k1(t) *
                        kDegPerHourPerRadPerSecond;
               },
               "settled output's even part in a_i at 1 g, over the scale factor"});
  d.push_back({"bias temperature coefficient", "", "(deg/h)/degC",
               [](const Term& t) { return t.uses(Variable::T) && !t.uses(Variable::Wi) && !t.uses(Variable::Y); },
               [&b, k1](const Eigen::VectorXd& t) {
                 return (b.output(t, {{Variable::T, 1.0}}) - b.output(t, {{Variable::T, -1.0}})) / 2.0 / k1(t) * kDegPerHourPerRadPerSecond;
               },
               "settled output's slope in T at zero rate, over the scale factor"});
  d.push_back({"scale-factor temperature coefficient", "", "ppm/degC",
               [](const Term& t) { return t.uses(Variable::T) && (t.uses(Variable::Wi) || t.uses(Variable::Y)); },
               [&b, k1](const Eigen::VectorXd& t) {
                 const auto slope = [&](double temp) {
                   return (b.output(t, {{Variable::Wi, 1e-3}, {Variable::T, temp}}) - b.output(t, {{Variable::Wi, -1e-3}, {Variable::T, temp}})) / 2e-3;
                 };
                 return (slope(1.0) - slope(-1.0)) / 2.0 / k1(t) * 1e6;
               },
               "the settled response's slope in w_i, its change per degC over the scale factor"});
  return d;
}

SheetEntry misalignment_entry(const model::ModelFile& m, bool about_p) {
  SheetEntry e;
  e.name = about_p ? "input-axis misalignment about p" : "input-axis misalignment about o";
  e.unit = "urad";
  e.derivation = "the input axis's angle from the nominal case frame (algorithm 1 on the first mounting; fixture included)";
  if (!m.misalignment) {
    e.status = SheetEntry::Status::Undetermined;
    e.reason = "the model has no [misalignment]: its first mounting was not aligned (no case excites the input axis enough)";
    return e;
  }
  e.terms.push_back("m_cs");
  e.value = (about_p ? m.misalignment->about_p : m.misalignment->about_o) * 1e6;
  e.expanded_uncertainty = 2.0 * (about_p ? m.misalignment->sd_p : m.misalignment->sd_o) * 1e6;
  if (e.expanded_uncertainty == 0.0) e.derivation += "; held at the nominal frame (sd 0): the plan does not excite that axis";
  return e;
}

std::string number(double v) { return std::isfinite(v) ? fmt::format("{:.4g}", v) : std::string("-"); }

std::string status_text(const SheetEntry& e) {
  switch (e.status) {
    case SheetEntry::Status::Determined: return "determined";
    case SheetEntry::Status::Undetermined: return "not determined";
    case SheetEntry::Status::NotSelected: return "not selected";
  }
  return "?";
}

std::string html_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

}  // namespace

ParameterSheet parameter_sheet(const model::ModelFile& model) {
  const bool gyro = model.sensor == dataset::SensorKind::Gyroscope;
  const Variable sensed = gyro ? Variable::Wi : Variable::Ai;
  const double k1 = compensate::static_sensitivity(model, sensed);
  if (!(std::isfinite(k1) && k1 != 0.0))
    throw InputError(fmt::format("the model has no {} term: no scale factor to state its parameters in input units",
                                 ident::variable_name(sensed)));
  ParameterSheet sheet;
  sheet.sensor_kind = dataset::to_string(model.sensor);
  sheet.sensor_name = model.name;
  sheet.output_unit = model.output_unit;
  const SheetBuilder builder(model);
  for (const Definition& d : gyro ? gyroscope_definitions(builder) : accelerometer_definitions(builder))
    sheet.entries.push_back(builder.entry(d));
  sheet.entries.push_back(misalignment_entry(model, true));
  sheet.entries.push_back(misalignment_entry(model, false));
  if (gyro) {
    const double per_rad = 180.0 / std::numbers::pi;
    sheet.entries.push_back(noise_entry(model, 1, k1, "angle random walk", "N", "deg/sqrt(h)", per_rad * 60.0, "white"));
    sheet.entries.push_back(noise_entry(model, 2, k1, "bias instability", "B", "deg/h", kDegPerHourPerRadPerSecond, "flicker"));
    sheet.entries.push_back(noise_entry(model, 3, k1, "rate random walk", "K", "(deg/h)/sqrt(h)", kDegPerHourPerRadPerSecond * 60.0,
                                        "random walk"));
    sheet.entries.push_back(noise_entry(model, 0, k1, "quantization", "Q", "arcsec", per_rad * 3600.0, "quantization"));
  } else {
    sheet.entries.push_back(noise_entry(model, 1, k1, "velocity random walk", "N", "ug/sqrt(Hz)", 1e6 / kG, "white"));
    sheet.entries.push_back(noise_entry(model, 2, k1, "bias instability", "B", "ug", 1e6 / kG, "flicker"));
    sheet.entries.push_back(noise_entry(model, 3, k1, "acceleration random walk", "K", "ug/sqrt(s)", 1e6 / kG, "random walk"));
    sheet.entries.push_back(noise_entry(model, 0, k1, "quantization", "Q", "m/s", 1.0, "quantization"));
  }

  // The conditions the model saw.
  const auto span = [&](Variable v) -> const model::ModelFile::Span* {
    const auto it = model.range.find(v);
    return it == model.range.end() ? nullptr : &it->second;
  };
  if (const auto* t = span(Variable::T); t && model.t_ref)
    sheet.conditions.push_back(fmt::format("temperature {:.1f} to {:.1f} degC", *model.t_ref + t->lowest, *model.t_ref + t->highest));
  else
    sheet.conditions.push_back("temperature: not varied in a way the model reads (no T term)");
  for (Variable v : {Variable::Ai, Variable::Ap, Variable::Ao}) {
    if (const auto* s = span(v)) sheet.conditions.push_back(fmt::format("{} {:.3g} to {:.3g} g", ident::variable_name(v), s->lowest / kG, s->highest / kG));
  }
  for (Variable v : {Variable::Wi, Variable::Wp, Variable::Wo}) {
    if (const auto* s = span(v))
      sheet.conditions.push_back(fmt::format("{} {:.4g} to {:.4g} deg/s", ident::variable_name(v), s->lowest * 180.0 / std::numbers::pi,
                                             s->highest * 180.0 / std::numbers::pi));
  }
  if (model.sample_period_s)
    sheet.conditions.push_back(fmt::format("frequency band 0 to {:.4g} Hz (sampled at {:.4g} Hz)", 0.5 / *model.sample_period_s,
                                           1.0 / *model.sample_period_s));
  const model::ModelFile::Conditions& c = model.conditions;
  if (c.duration_s) sheet.conditions.push_back(fmt::format("test duration {:.1f} s over {} case(s)", *c.duration_s, c.cases.size()));
  if (!c.cases.empty()) sheet.conditions.push_back(fmt::format("cases {}", fmt::join(c.cases, ", ")));
  if (!c.source.empty()) sheet.conditions.push_back("data " + c.source);
  sheet.conditions.push_back("software " + (c.software.empty() ? std::string("not stated in the model") : c.software));
  sheet.conditions.push_back("date " + (c.date.empty() ? std::string("not stated in the model") : c.date));
  return sheet;
}

std::string sheet_markdown(const ParameterSheet& sheet) {
  std::string s = fmt::format("# Parameter sheet: {} {}\n\n", sheet.sensor_kind, sheet.sensor_name.empty() ? "(unnamed)" : sheet.sensor_name);
  s += "Expanded uncertainty U with coverage factor k = 2 (about 95 %). Each value derives from the model file as the last "
       "column says; a parameter the plan did not determine is stated as such, never as 0.\n\n";
  s += "| parameter | symbol | value | U (k = 2) | unit | derived from |\n|---|---|---|---|---|---|\n";
  for (const SheetEntry& e : sheet.entries) {
    if (e.status == SheetEntry::Status::Determined) {
      s += fmt::format("| {} | {} | {} | {} | {} | {} ({}) |\n", e.name, e.symbol, number(e.value), number(e.expanded_uncertainty), e.unit,
                       e.derivation, fmt::join(e.terms, ", "));
    } else {
      s += fmt::format("| {} | {} | {} | | {} | {} |\n", e.name, e.symbol, status_text(e), e.unit, e.reason);
    }
  }
  s += "\n## Conditions\n\n";
  for (const std::string& c : sheet.conditions) s += "- " + c + "\n";
  return s;
}

std::string sheet_html(const ParameterSheet& sheet) {
  std::string s = "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>Parameter sheet</title>\n"
                  "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}td,th{border:1px solid #999;"
                  "padding:3px 8px;text-align:left}td.n{text-align:right;font-variant-numeric:tabular-nums}tr.u td{color:#777}</style>"
                  "</head><body>\n";
  s += fmt::format("<h1>Parameter sheet: {} {}</h1>\n", html_escape(sheet.sensor_kind), html_escape(sheet.sensor_name));
  s += "<p>Expanded uncertainty U with coverage factor k = 2 (about 95 %). The last column traces each value to the model.</p>\n";
  s += "<table><tr><th>parameter</th><th>symbol</th><th>value</th><th>U (k = 2)</th><th>unit</th><th>derived from</th></tr>\n";
  for (const SheetEntry& e : sheet.entries) {
    if (e.status == SheetEntry::Status::Determined) {
      s += fmt::format("<tr><td>{}</td><td>{}</td><td class=n>{}</td><td class=n>{}</td><td>{}</td><td>{} ({})</td></tr>\n",
                       html_escape(e.name), e.symbol, number(e.value), number(e.expanded_uncertainty), html_escape(e.unit),
                       html_escape(e.derivation), html_escape(fmt::format("{}", fmt::join(e.terms, ", "))));
    } else {
      s += fmt::format("<tr class=u><td>{}</td><td>{}</td><td>{}</td><td></td><td>{}</td><td>{}</td></tr>\n", html_escape(e.name),
                       e.symbol, status_text(e), html_escape(e.unit), html_escape(e.reason));
    }
  }
  s += "</table>\n<h2>Conditions</h2>\n<ul>\n";
  for (const std::string& c : sheet.conditions) s += "<li>" + html_escape(c) + "</li>\n";
  return s + "</ul>\n</body></html>\n";
}

nlohmann::json sheet_json(const ParameterSheet& sheet) {
  nlohmann::json j;
  j["schema"] = "inertia-sheet-1";
  j["sensor"] = sheet.sensor_kind;
  j["sensor_name"] = sheet.sensor_name;
  j["output_unit"] = sheet.output_unit;
  j["coverage_factor"] = 2;
  j["parameters"] = nlohmann::json::array();
  for (const SheetEntry& e : sheet.entries) {
    nlohmann::json p{{"name", e.name}, {"symbol", e.symbol}, {"unit", e.unit}, {"status", status_text(e)}, {"derivation", e.derivation}};
    if (e.status == SheetEntry::Status::Determined) {
      p["value"] = e.value;
      if (std::isfinite(e.expanded_uncertainty)) p["expanded_uncertainty"] = e.expanded_uncertainty;
      p["terms"] = e.terms;
    } else {
      p["reason"] = e.reason;
    }
    j["parameters"].push_back(p);
  }
  j["conditions"] = sheet.conditions;
  return j;
}

}  // namespace inertia::report
