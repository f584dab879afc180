#include "hal/sim/sensor_truth.hpp"

#include <cmath>
#include <numeric>
#include <string_view>
#include <vector>

#include "common/input_error.hpp"
#include "common/units.hpp"
#include "hal/sim/sensors/accelerometer_model_terms.hpp"

namespace inertia::sim {

namespace {

template <class Params>
struct ScalarField {
  std::string_view name;
  double Params::*member;
};

using A = AccelerometerParams;
constexpr ScalarField<A> kAccelerometerFields[] = {
    {"k_i", &A::k_i},         {"k_b", &A::k_b},
    {"k_s", &A::k_s},         {"k_a", &A::k_a},
    {"k_oq", &A::k_oq},       {"k_ip", &A::k_ip},
    {"k_io", &A::k_io},       {"k_po", &A::k_po},
    {"k_ii", &A::k_ii},       {"k_pp", &A::k_pp},
    {"k_oo", &A::k_oo},       {"b_ii_rad_s", &A::b_ii_rad_s},
    {"b_pp_rad_s", &A::b_pp_rad_s}, {"b_oo_rad_s", &A::b_oo_rad_s},
    {"alpha_p_rad", &A::alpha_p_rad}, {"alpha_o_rad", &A::alpha_o_rad},
    {"white_sd_g", &A::white_sd_g},   {"pink_sd_g", &A::pink_sd_g},
    {"brown_sd_g", &A::brown_sd_g},   {"pink_min_hz", &A::pink_min_hz},
    {"bias_tc_g_per_degc", &A::bias_tc_g_per_degc}, {"scale_tc_per_degc", &A::scale_tc_per_degc},
};

using F = FogParams;
constexpr ScalarField<F> kFogFields[] = {
    {"s0", &F::s0},           {"eps_t_ppm_per_degc", &F::eps_t_ppm_per_degc},
    {"c_f1", &F::c_f1},       {"c_i", &F::c_i},
    {"alpha_p_rad", &F::alpha_p_rad}, {"alpha_o_rad", &F::alpha_o_rad},
    {"c_t1", &F::c_t1},       {"c_t2", &F::c_t2},
    {"drift_rad_s", &F::drift_rad_s}, {"noise_sd_rad_s", &F::noise_sd_rad_s},
};

// Noise levels and corners must be physical; everything else may take any finite value.
bool must_be_non_negative(std::string_view name) {
  return name.ends_with("_sd_g") || name == "noise_sd_rad_s";
}
bool must_be_positive(std::string_view name) {
  return name.starts_with("b_") || name == "pink_min_hz" || name == "s0";
}

template <class Params, std::size_t N>
bool apply_scalar(const ScalarField<Params> (&fields)[N], Params& p, const config::TruthValue& v) {
  for (const auto& f : fields) {
    if (f.name != v.name) continue;
    if (v.is_array) throw InputError(v.where, "truth." + v.name + " must be a number, not an array");
    const double x = v.values.front();
    if (must_be_non_negative(f.name) && x < 0.0) throw InputError(v.where, "truth." + v.name + " must be >= 0");
    if (must_be_positive(f.name) && !(x > 0.0)) throw InputError(v.where, "truth." + v.name + " must be > 0");
    p.*(f.member) = x;
    return true;
  }
  return false;
}

template <std::size_t Order>
bool apply_transfer(std::string_view prefix, DiscreteTransferFunction<Order>& tf, const config::TruthValue& v) {
  const bool num = v.name == std::string(prefix) + "_num";
  const bool den = v.name == std::string(prefix) + "_den";
  if (!num && !den) return false;
  if (!v.is_array || v.values.size() != Order + 1) {
    throw InputError(v.where, "truth." + v.name + " must be an array of " + std::to_string(Order + 1) +
                                  " coefficients (powers of q^-1)");
  }
  auto& dst = num ? tf.num : tf.den;
  std::copy(v.values.begin(), v.values.end(), dst.begin());
  if (den && dst[0] != 1.0) throw InputError(v.where, "truth." + v.name + "[0] must be 1 (monic denominator)");
  return true;
}

template <class Params, std::size_t N>
std::string known_names(const ScalarField<Params> (&fields)[N]) {
  std::string s;
  for (const auto& f : fields) s += (s.empty() ? "" : ", ") + std::string(f.name);
  return s;
}

template <std::size_t Order>
void put_transfer(toml::table& t, const std::string& prefix, const DiscreteTransferFunction<Order>& tf) {
  toml::array num, den;
  for (const double x : tf.num) num.push_back(x);
  for (const double x : tf.den) den.push_back(x);
  t.insert_or_assign(prefix + "_num", std::move(num));
  t.insert_or_assign(prefix + "_den", std::move(den));
}

template <std::size_t Order>
double static_gain(const DiscreteTransferFunction<Order>& tf) {
  const double n = std::accumulate(tf.num.begin(), tf.num.end(), 0.0);
  const double d = std::accumulate(tf.den.begin(), tf.den.end(), 0.0);
  return d == 0.0 ? 0.0 : n / d;
}

void put_term(toml::table& t, std::string_view name, double value) {
  if (value != 0.0) t.insert_or_assign(name, value);
}

}  // namespace

AccelerometerParams accelerometer_params(const config::SensorUnderTest& sensor) {
  AccelerometerParams p;
  for (const config::TruthValue& v : sensor.truth) {
    if (!apply_scalar(kAccelerometerFields, p, v)) {
      throw InputError(v.where, "unknown accelerometer truth parameter '" + v.name +
                                    "' (known: " + known_names(kAccelerometerFields) + ")");
    }
  }
  return p;
}

FogParams fog_params(const config::SensorUnderTest& sensor) {
  FogParams p;
  for (const config::TruthValue& v : sensor.truth) {
    if (apply_scalar(kFogFields, p, v) || apply_transfer("noise", p.noise, v) ||
        apply_transfer("g_sens_i", p.g_sens_i, v) || apply_transfer("g_sens_p", p.g_sens_p, v) ||
        apply_transfer("g_sens_o", p.g_sens_o, v)) {
      continue;
    }
    throw InputError(v.where, "unknown gyroscope truth parameter '" + v.name + "' (known: " +
                                  known_names(kFogFields) +
                                  ", noise_num, noise_den, g_sens_{i,p,o}_{num,den})");
  }
  return p;
}

toml::table to_toml(const AccelerometerParams& p) {
  toml::table t;
  for (const auto& f : kAccelerometerFields) t.insert_or_assign(f.name, p.*(f.member));
  return t;
}

toml::table to_toml(const FogParams& p) {
  toml::table t;
  for (const auto& f : kFogFields) t.insert_or_assign(f.name, p.*(f.member));
  put_transfer(t, "noise", p.noise);
  put_transfer(t, "g_sens_i", p.g_sens_i);
  put_transfer(t, "g_sens_p", p.g_sens_p);
  put_transfer(t, "g_sens_o", p.g_sens_o);
  return t;
}

toml::array to_toml(const Eigen::Matrix3d& m) {
  toml::array rows;
  for (int r = 0; r < 3; ++r) rows.push_back(toml::array{m(r, 0), m(r, 1), m(r, 2)});
  return rows;
}

toml::table model_terms(const AccelerometerParams& p, toml::table* notes) {
  toml::table t;
  for (const auto& [name, value] : accelerometer_model_terms(p)) t.insert_or_assign(name, value);
  if (notes != nullptr) {
    const auto hp = [](double b) {
      return "high-pass K s/(s + b), b = " + std::to_string(b) + " rad/s: high-frequency gain listed, DC gain 0";
    };
    if (p.k_ii != 0.0) notes->insert_or_assign("a_i^2", hp(p.b_ii_rad_s));
    if (p.k_pp != 0.0) notes->insert_or_assign("a_p^2", hp(p.b_pp_rad_s));
    if (p.k_oo != 0.0) notes->insert_or_assign("a_o^2", hp(p.b_oo_rad_s));
  }
  return t;
}

toml::table model_terms(const FogParams& p, toml::table* notes) {
  toml::table t;
  put_term(t, "1", p.drift_rad_s / p.s0);
  put_term(t, "w_i", p.c_i / p.s0);
  put_term(t, "T", p.c_t1 / p.s0);
  put_term(t, "T[k-1]", p.c_t2 / p.s0);
  // Output-multiplied terms carry their denominator coefficient (model_file.hpp): y (1 + eps T + c_f1 w_i) = ...
  put_term(t, "y*T", 1e-6 * p.eps_t_ppm_per_degc);
  put_term(t, "y*w_i", p.c_f1);
  put_term(t, "a_i", static_gain(p.g_sens_i) / p.s0);
  put_term(t, "a_p", static_gain(p.g_sens_p) / p.s0);
  put_term(t, "a_o", static_gain(p.g_sens_o) / p.s0);
  if (notes != nullptr) {
    for (const char* v : {"a_i", "a_p", "a_o"}) {
      if (t.contains(v)) notes->insert_or_assign(v, "static gain of a discrete transfer function (eq. 5): dynamics in [params]");
    }
    notes->insert_or_assign("noise", "coloured noise B(q)/A(q) n(k): see [params] noise_num/noise_den");
  }
  return t;
}

}  // namespace inertia::sim
