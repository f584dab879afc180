#include "analyzer/report/parameter_sheet.hpp"

#include "analyzer/model/coefficient_uncertainty.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <tuple>

#include <fmt/ranges.h>

#include "analyzer/compensate/static_response.hpp"
#include "analyzer/noise/noise_fit.hpp"
#include "analyzer/report/gnuplot.hpp"
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
using VectorFunction = std::function<Eigen::VectorXd(const Eigen::VectorXd&)>;

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
  explicit SheetBuilder(const model::ModelFile& m) : m_(m), theta_(model::coefficient_vector(m)) {}

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
    e.value = d.value(theta_);
    const VectorFunction value = [&d](const Eigen::VectorXd& t) { return Eigen::VectorXd::Constant(1, d.value(t)); };
    e.expanded_uncertainty = expanded_uncertainty(value)(0);
    if (!std::isfinite(e.value)) {
      e.status = SheetEntry::Status::Undetermined;
      e.reason = "not computable from the model file: it states no characterized range of the input (characterize writes [range])";
    }
    return e;
  }

  /// The delta method's expanded uncertainty (k = 2) of each component of f(theta)
  /// (model::propagated_covariance).
  [[nodiscard]] Eigen::VectorXd expanded_uncertainty(const VectorFunction& f) const {
    return model::propagated_covariance(m_, f).diagonal().unaryExpr([](double v) { return 2.0 * std::sqrt(std::max(0.0, v)); });
  }

  [[nodiscard]] const model::ModelFile& model() const { return m_; }
  [[nodiscard]] const Eigen::VectorXd& theta() const { return theta_; }

 private:
  const model::ModelFile& m_;
  Eigen::VectorXd theta_;
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

// The plots.

/// The points a characterized range is drawn at, evenly spaced: both ends and the middle among them.
constexpr int kRangePoints = 41;

std::vector<double> range_grid(const model::ModelFile::Span& span) {
  std::vector<double> x(kRangePoints);
  for (int i = 0; i < kRangePoints; ++i)
    x[static_cast<std::size_t>(i)] = span.lowest + (span.highest - span.lowest) * i / (kRangePoints - 1.0);
  return x;
}

std::vector<double> to_std_vector(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }

/// The settled response to `sensed` at each of `x` (the other inputs 0) less its least-squares straight line over `x`.
Eigen::VectorXd deviation_from_least_squares_line(const SheetBuilder& b, const Eigen::VectorXd& theta, Variable sensed,
                                                  const std::vector<double>& x) {
  const auto n = static_cast<Index>(x.size());
  Eigen::VectorXd y(n);
  Eigen::MatrixXd line(n, 2);
  for (Index i = 0; i < n; ++i) {
    const double at = x[static_cast<std::size_t>(i)];
    y(i) = b.output(theta, {{sensed, at}});
    line(i, 0) = 1.0;
    line(i, 1) = at;
  }
  return y - line * line.colPivHouseholderQr().solve(y);
}

SheetSeries curve(std::string title, std::vector<double> y, bool dashed = false) {
  SheetSeries s;
  s.title = std::move(title);
  s.y = std::move(y);
  s.dashed = dashed;
  return s;
}

/// Gives `series` the band +-U (k = 2) at each point, and says in `trace` whether it has one.
void attach_band(SheetSeries& series, const Eigen::VectorXd& u, std::string& trace) {
  if (u.allFinite() && u.maxCoeff() > 0.0) {
    series.expanded_uncertainty = to_std_vector(u);
    trace += " Band: +-U (k = 2) by the delta method with the model's coefficient covariance, as the table's.";
  } else {
    trace += " No band: no coefficient the curve depends on has an uncertainty in the model.";
  }
}

/// The settled response to the sensed input less its least-squares line over the characterized range, with its band.
SheetPlot nonlinearity_plot(const SheetBuilder& b, Variable sensed, bool gyro) {
  SheetPlot p;
  p.name = "scale-factor nonlinearity";
  const model::ModelFile& m = b.model();
  const std::string variable = ident::variable_name(sensed);
  const auto it = m.range.find(sensed);
  if (it == m.range.end()) {
    p.not_drawable = fmt::format("the model states no characterized range of {} (characterize writes [range])", variable);
    return p;
  }
  const model::ModelFile::Span span = it->second;
  const double per_si = gyro ? 180.0 / std::numbers::pi : 1.0 / kG;   // the plot's input unit per SI unit
  const char* input_unit = gyro ? "deg/s" : "g";
  if (!(span.highest > span.lowest)) {
    p.not_drawable =
        fmt::format("the characterized range of {} is the single value {:.4g} {}", variable, span.lowest * per_si, input_unit);
    return p;
  }
  const std::vector<double> x = range_grid(span);
  const VectorFunction deviation = [&b, sensed, &x](const Eigen::VectorXd& t) {
    return deviation_from_least_squares_line(b, t, sensed, x);
  };
  const Eigen::VectorXd y = deviation(b.theta());
  if (!y.allFinite()) {
    p.not_drawable = fmt::format("the model's settled response to {} is not finite over its characterized range", variable);
    return p;
  }
  const double full_scale = std::max(std::abs(span.lowest), std::abs(span.highest));
  const double k1 = compensate::static_sensitivity(m, sensed, b.theta());
  // Rounding alone leaves a straight response some 1e-16 of full scale off its line.
  if (y.cwiseAbs().maxCoeff() <= 1e-12 * std::abs(k1 * full_scale)) {
    p.not_drawable = fmt::format("the model's settled response to {0} is a straight line over its characterized range: no term is "
                                 "nonlinear in {0}",
                                 variable);
    return p;
  }
  const std::string output_unit = m.output_unit.empty() ? std::string("output unit") : m.output_unit;
  p.x_label = fmt::format("{} [{}]", variable, input_unit);
  p.y_label = fmt::format("deviation [{}]", output_unit);
  for (double v : x) p.x.push_back(v * per_si);
  p.y2_label = "ppm of full scale";
  p.y2_per_y = 1e6 / std::abs(k1 * full_scale);
  p.trace = fmt::format("The model's settled response to {0} (every lag at its value, the other inputs 0) at {1} points over the "
                        "characterized range {2:.4g} to {3:.4g} {4}, less its least-squares straight line over those points, in {5}; "
                        "right axis: over the static scale factor times full scale ({6:.4g} {4}). The table's nonlinearity measures "
                        "from the zero-input output plus the static scale factor's line instead.",
                        variable, kRangePoints, span.lowest * per_si, span.highest * per_si, input_unit, output_unit, full_scale * per_si);
  SheetSeries series = curve("settled response less its least-squares line", to_std_vector(y));
  attach_band(series, b.expanded_uncertainty(deviation), p.trace);
  p.series.push_back(std::move(series));
  return p;
}

/// The Allan deviation the model's [noise] terms imply in input units, each term's and their sum.
SheetPlot allan_deviation_plot(const model::ModelFile& m, double sensitivity, bool gyro) {
  SheetPlot p;
  p.name = "Allan deviation of the noise terms";
  p.log_log = true;
  const double scale = (gyro ? kDegPerHourPerRadPerSecond : 1e6 / kG) / std::abs(sensitivity);   // output unit -> plotted unit
  std::array<double, noise::kNoiseTerms> all{};
  std::vector<std::size_t> present;
  for (std::size_t slot = 0; slot < m.noise.values.size(); ++slot) {
    if (!m.noise.values[slot] || !(*m.noise.values[slot] > 0.0)) continue;   // log axes: a term of 0 has no line
    all[slot] = *m.noise.values[slot] * scale;
    present.push_back(slot);
  }
  if (present.empty()) {
    p.not_drawable = "the model has no [noise] terms (Q, N, B, K, R) above 0: no noise analysis of its static stretches resolved one";
    return p;
  }
  p.x_label = "tau [s]";
  p.y_label = fmt::format("Allan deviation [{}]", gyro ? "deg/h" : "ug");
  for (int i = 0; i <= 70; ++i) p.x.push_back(std::pow(10.0, -3.0 + i / 10.0));   // 1e-3 .. 1e4 s, ten per decade
  const auto deviation = [&p](const std::array<double, noise::kNoiseTerms>& c) {
    std::vector<double> sigma;
    for (double tau : p.x) sigma.push_back(std::sqrt(noise::model_avar(c, tau)));
    return sigma;
  };
  p.series.push_back(curve("sum of the terms", deviation(all)));
  std::vector<std::string> keys;
  for (std::size_t slot : present) {
    std::array<double, noise::kNoiseTerms> alone{};
    alone[slot] = all[slot];
    const auto term = static_cast<noise::NoiseTerm>(slot);
    const std::string title = fmt::format("{}: {}", noise::noise_term_name(term), noise::noise_term_meaning(term));
    p.series.push_back(curve(title, deviation(alone), true));
    keys.emplace_back(model::ModelFile::NoiseTerms::kKeys[slot]);
  }
  p.trace = fmt::format("sigma^2(tau) = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2 (IEEE Std 952 Annex C) of the "
                        "model's [noise] terms {} over the static scale factor, for tau from 1e-3 to 1e4 s: each term alone dashed, "
                        "their sum solid.",
                        fmt::join(keys, ", "));
  return p;
}

/// The bias over the characterized temperatures, with its band, where the model's bias depends on T.
SheetPlot bias_temperature_plot(const SheetBuilder& b, Variable sensed, bool gyro, const SheetEntry& temperature_coefficient) {
  SheetPlot p;
  p.name = "bias over temperature";
  const model::ModelFile& m = b.model();
  const auto it = m.range.find(Variable::T);
  if (it == m.range.end() || !m.t_ref || !(it->second.highest > it->second.lowest)) {
    p.not_drawable = "the model states no characterized temperature range (a [range] of T and its t_ref)";
    return p;
  }
  if (temperature_coefficient.status != SheetEntry::Status::Determined) {
    p.not_drawable = fmt::format("the model's bias temperature coefficient is {}: {}", status_text(temperature_coefficient),
                                 temperature_coefficient.reason);
    return p;
  }
  const double scale = gyro ? kDegPerHourPerRadPerSecond : 1e6 / kG;   // input SI unit -> the bias entry's unit
  const std::vector<double> temperatures = range_grid(it->second);    // T = temperature - t_ref
  const VectorFunction bias = [&b, &m, sensed, &temperatures, scale](const Eigen::VectorXd& t) {
    const double k1 = compensate::static_sensitivity(m, sensed, t);
    Eigen::VectorXd out(static_cast<Index>(temperatures.size()));
    for (std::size_t i = 0; i < temperatures.size(); ++i)
      out(static_cast<Index>(i)) = b.output(t, {{Variable::T, temperatures[i]}}) / k1 * scale;
    return out;
  };
  const Eigen::VectorXd y = bias(b.theta());
  if (!y.allFinite()) {
    p.not_drawable = "the model's settled output at zero input is not finite over its characterized temperature range";
    return p;
  }
  const char* unit = gyro ? "deg/h" : "ug";
  p.x_label = "temperature [degC]";
  p.y_label = fmt::format("bias [{}]", unit);
  for (double t : temperatures) p.x.push_back(*m.t_ref + t);
  p.trace = fmt::format("The table's bias (the settled output at zero input over the static scale factor) at {} temperatures over the "
                        "characterized range {:.1f} to {:.1f} degC (t_ref {:.1f} degC plus the model's T), in {}.",
                        kRangePoints, *m.t_ref + it->second.lowest, *m.t_ref + it->second.highest, *m.t_ref, unit);
  SheetSeries series = curve("bias", to_std_vector(y));
  attach_band(series, b.expanded_uncertainty(bias), p.trace);
  p.series.push_back(std::move(series));
  return p;
}

/// The page's plot colours, one per series in order.
constexpr std::array<const char*, 6> kPlotColours{"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};

/// `plot`'s columns for gnuplot: x, then each series' y and, where it has a band, its U.
void write_plot_columns(const std::filesystem::path& file, const SheetPlot& plot) {
  std::ofstream f(file);
  for (std::size_t i = 0; i < plot.x.size(); ++i) {
    f << fmt::format("{:.10g}", plot.x[i]);
    for (const SheetSeries& s : plot.series) {
      f << fmt::format(" {:.10g}", s.y[i]);
      if (!s.expanded_uncertainty.empty()) f << fmt::format(" {:.10g}", s.expanded_uncertainty[i]);
    }
    f << '\n';
  }
}

/// The tic step of 1, 2 or 5 times a power of ten nearest `step` in ratio.
double round_step(double step) {
  const double decade = std::pow(10.0, std::floor(std::log10(step)));
  double best = decade;
  for (double m : {2.0, 5.0, 10.0}) {
    if (std::abs(std::log(m * decade / step)) < std::abs(std::log(best / step))) best = m * decade;
  }
  return best;
}

/// The gnuplot commands that draw `plot` from the columns write_plot_columns wrote to `data`.
std::string plot_script(const SheetPlot& plot, const std::filesystem::path& data) {
  std::string g = "set grid\nset key below\n";
  g += fmt::format("set xlabel {}\nset ylabel {}\n", gnuplot_quoted(plot.x_label), gnuplot_quoted(plot.y_label));
  if (plot.log_log) g += "set logscale xy\nset format x '10^{%L}'\nset format y '10^{%L}'\n";
  if (plot.y2_per_y != 0.0) {
    // gnuplot's own tics on a linked axis come too sparse (often 0 alone): the step is given, about six over the data.
    double lowest = std::numeric_limits<double>::infinity(), highest = -lowest;
    for (const SheetSeries& s : plot.series) {
      for (std::size_t i = 0; i < s.y.size(); ++i) {
        const double u = s.expanded_uncertainty.empty() ? 0.0 : s.expanded_uncertainty[i];
        lowest = std::min(lowest, s.y[i] - u);
        highest = std::max(highest, s.y[i] + u);
      }
    }
    const double span = (highest - lowest) * std::abs(plot.y2_per_y);
    g += fmt::format("set ytics nomirror\nset y2tics {}\nset link y2 via y*{:.10g} inverse y/{:.10g}\nset y2label {}\n",
                     span > 0.0 ? fmt::format("{:.3g}", round_step(span / 6.0)) : std::string(), plot.y2_per_y, plot.y2_per_y,
                     gnuplot_quoted(plot.y2_label));
  }
  const std::string file = gnuplot_quoted(data.string());
  std::vector<std::string> parts;
  int column = 2;
  for (std::size_t k = 0; k < plot.series.size(); ++k) {
    const SheetSeries& s = plot.series[k];
    const char* colour = kPlotColours[k % kPlotColours.size()];
    const int y = column++;
    if (!s.expanded_uncertainty.empty()) {
      const int u = column++;
      parts.push_back(fmt::format("{0} u 1:(${1}-${2}):(${1}+${2}) w filledcurves fs transparent solid 0.2 noborder lc rgb '{3}' "
                                  "t '+-U (k = 2)'",
                                  file, y, u, colour));
    }
    parts.push_back(fmt::format("{} u 1:{} w l lw {} dt {} lc rgb '{}' t {}", file, y, s.dashed ? 1.5 : 2.0, s.dashed ? 2 : 1, colour,
                                gnuplot_quoted(s.title)));
  }
  return g + fmt::format("plot {}\n", fmt::join(parts, ", \\\n  "));
}

/// The page's plots: each an inline SVG with its caption, or the sentence saying why it is not drawn.
std::string plots_html(const std::vector<SheetPlot>& plots) {
  std::string s = "<h2>Plots</h2>\n";
  std::optional<ScratchDirectory> scratch;
  std::string no_scratch;
  try {
    scratch.emplace("inertia-sheet");
  } catch (const std::filesystem::filesystem_error& e) {
    no_scratch = e.what();
  }
  for (std::size_t k = 0; k < plots.size(); ++k) {
    const SheetPlot& p = plots[k];
    std::string capitalized = p.name;
    if (!capitalized.empty()) capitalized[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(capitalized[0])));
    if (!p.not_drawable.empty()) {
      s += fmt::format("<p>{} is not plotted: {}.</p>\n", html_escape(capitalized), html_escape(p.not_drawable));
      continue;
    }
    std::optional<std::string> svg;
    if (scratch) {
      const std::filesystem::path data = scratch->path() / fmt::format("plot{}.dat", k);
      write_plot_columns(data, p);
      svg = gnuplot_svg(plot_script(p, data), scratch->path());
    }
    if (!svg) {
      s += fmt::format("<p>{} is not plotted: {}.</p>\n", html_escape(capitalized),
                       html_escape(scratch ? std::string("gnuplot, which draws it, is not installed or failed on its script")
                                           : "no scratch directory for gnuplot's files (" + no_scratch + ")"));
      continue;
    }
    s += fmt::format("<figure>\n{}<figcaption><b>{}.</b> {}</figcaption>\n</figure>\n",
                     svg_with_prefixed_ids(*svg, fmt::format("plot{}-", k)), html_escape(capitalized), html_escape(p.trace));
  }
  return s;
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
  const auto bias_temperature_coefficient =
      std::find_if(sheet.entries.begin(), sheet.entries.end(), [](const SheetEntry& e) { return e.name == "bias temperature coefficient"; });
  sheet.plots.push_back(nonlinearity_plot(builder, sensed, gyro));
  sheet.plots.push_back(allan_deviation_plot(model, k1, gyro));
  sheet.plots.push_back(bias_temperature_plot(builder, sensed, gyro, *bias_temperature_coefficient));

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
                  "padding:3px 8px;text-align:left}td.n{text-align:right;font-variant-numeric:tabular-nums}tr.u td{color:#777}"
                  "figure{margin:1.5em 0;max-width:52em}figure svg{display:block;width:100%;height:auto}figcaption{color:#333}</style>"
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
  s += "</ul>\n";
  if (!sheet.plots.empty()) s += plots_html(sheet.plots);
  return s + "</body></html>\n";
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
