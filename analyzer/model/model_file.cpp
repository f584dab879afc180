#include "analyzer/model/model_file.hpp"
#include "common/atomic_file.hpp"
#include "common/toml_text.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <memory>
#include <system_error>
#include <toml++/toml.h>
#include <unistd.h>

#include <fmt/format.h>

#include "common/input_error.hpp"

namespace inertia::model {

std::optional<double> ModelFile::coefficient(const ident::Term& term) const {
  for (const ModelTerm& t : terms) {
    if (t.term == term) return t.coefficient;
  }
  return std::nullopt;
}

namespace {

SourcePosition position_of(const toml::source_region& region, const std::string& file) {
  return SourcePosition{file, region.begin.line, region.begin.column};
}

double finite_number(const toml::node& node, const std::string& file, const std::string& what) {
  if (node.is_number()) {
    if (const auto v = node.value<double>(); v && std::isfinite(*v)) return *v;
  }
  throw InputError(position_of(node.source(), file), fmt::format("{} must be a finite number", what));
}

// Term keys of a table in file order (toml::table iterates in key order, not file order).
std::vector<std::pair<const toml::key*, const toml::node*>> in_file_order(const toml::table& table) {
  std::vector<std::pair<const toml::key*, const toml::node*>> entries;
  for (const auto& [key, node] : table) entries.emplace_back(&key, &node);
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
    const auto& pa = a.first->source().begin;
    const auto& pb = b.first->source().begin;
    return pa.line != pb.line ? pa.line < pb.line : pa.column < pb.column;
  });
  return entries;
}

ident::Term term_at(const toml::key& key, const std::string& file, std::string_view table) {
  try {
    return ident::parse_term(key.str());
  } catch (const InputError& e) {
    throw InputError(position_of(key.source(), file), fmt::format("[{}]: {}", table, e.what()));
  }
}

const toml::table* optional_table(const toml::table& root, std::string_view key, const std::string& file) {
  const toml::node* node = root.get(key);
  if (node == nullptr) return nullptr;
  if (!node->is_table()) {
    throw InputError(position_of(node->source(), file), fmt::format("'{}' must be a table, [{}]", key, key));
  }
  return node->as_table();
}


// A 3x3 rotation matrix [[..], [..], [..]] (tolerance dataset::kRotationTolerance).
frames::Dcm rotation_at(const toml::node& m, const std::string& file, const std::string& key) {
  frames::Dcm out;
  const toml::array* rows = m.as_array();
  const auto bad = [&](const toml::node& at) {
    return InputError(position_of(at.source(), file), fmt::format("'{}' must be a 3x3 array of numbers, [[..], [..], [..]]", key));
  };
  if (rows == nullptr || rows->size() != 3) throw bad(m);
  for (std::size_t r = 0; r < 3; ++r) {
    const toml::array* row = (*rows)[r].as_array();
    if (row == nullptr || row->size() != 3) throw bad((*rows)[r]);
    for (std::size_t c = 0; c < 3; ++c) {
      out(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = finite_number((*row)[c], file, fmt::format("'{}' entry", key));
    }
  }
  if (!frames::is_rotation(out, dataset::kRotationTolerance)) {
    throw InputError(position_of(m.source(), file),
                     fmt::format("{} is not a rotation (max |M M^T - I| = {:.3g}, det = {:.9g}, tolerance {})", key,
                                 (out * out.transpose() - frames::Dcm::Identity()).cwiseAbs().maxCoeff(), out.determinant(),
                                 dataset::kRotationTolerance));
  }
  return out;
}

// An input variable named by a [range] key: a term of one plain, unlagged factor.
ident::Variable range_variable(const toml::key& key, const std::string& file) {
  const auto bad = [&] {
    return InputError(position_of(key.source(), file),
                      fmt::format("[range]: '{}' is not an input variable (a_i, a_x, w_i, w_x, T, ...)", key.str()));
  };
  ident::Term term;
  try {
    term = ident::parse_term(key.str());
  } catch (const InputError&) {
    throw bad();
  }
  if (term.factors().size() != 1) throw bad();
  const ident::Factor& f = term.factors().front();
  if (f.lag != 0 || f.power != 1 || f.function != ident::FactorFunction::Plain) throw bad();
  return f.variable;
}

std::optional<std::string> optional_string(const toml::table& root, std::string_view key, const std::string& file) {
  const toml::node* node = root.get(key);
  if (node == nullptr) return std::nullopt;
  if (!node->is_string()) throw InputError(position_of(node->source(), file), fmt::format("'{}' must be a string", key));
  return *node->value<std::string>();
}

std::optional<double> optional_positive(const toml::table& root, std::string_view key, const std::string& file) {
  const toml::node* node = root.get(key);
  if (node == nullptr) return std::nullopt;
  const double v = finite_number(*node, file, std::string(key));
  if (!(v > 0.0)) throw InputError(position_of(node->source(), file), fmt::format("'{}' must be positive", key));
  return v;
}

// [covariance]: `terms` (each term of [terms] once) and `matrix`, reordered to [terms]' order.
Eigen::MatrixXd read_covariance(const toml::table& table, const std::vector<ModelTerm>& terms, const std::string& file,
                                const toml::node& at) {
  const toml::node* names = table.get("terms");
  const toml::node* matrix = table.get("matrix");
  if (names == nullptr || !names->is_array() || matrix == nullptr || !matrix->is_array()) {
    throw InputError(position_of(at.source(), file), "[covariance] needs 'terms' (an array of terms) and 'matrix'");
  }
  const toml::array& name_array = *names->as_array();
  const std::size_t n = terms.size();
  std::vector<Eigen::Index> slot;   // file row -> index in `terms`
  for (const toml::node& name : name_array) {
    if (!name.is_string()) throw InputError(position_of(name.source(), file), "[covariance] terms must be strings");
    ident::Term term;
    try {
      term = ident::parse_term(*name.value<std::string>());
    } catch (const InputError& e) {
      throw InputError(position_of(name.source(), file), fmt::format("[covariance]: {}", e.what()));
    }
    const auto it = std::find_if(terms.begin(), terms.end(), [&](const ModelTerm& t) { return t.term == term; });
    if (it == terms.end())
      throw InputError(position_of(name.source(), file), fmt::format("[covariance]: term '{}' is not in [terms]", term.to_string()));
    const Eigen::Index index = it - terms.begin();
    if (std::find(slot.begin(), slot.end(), index) != slot.end())
      throw InputError(position_of(name.source(), file), fmt::format("[covariance]: term '{}' given twice", term.to_string()));
    slot.push_back(index);
  }
  if (slot.size() != n) {
    throw InputError(position_of(names->source(), file),
                     fmt::format("[covariance] terms: {} given, [terms] has {}", slot.size(), n));
  }
  const toml::array& rows = *matrix->as_array();
  if (rows.size() != n) {
    throw InputError(position_of(matrix->source(), file), fmt::format("[covariance] matrix: {} rows, {} needed", rows.size(), n));
  }
  Eigen::MatrixXd c(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  for (std::size_t r = 0; r < n; ++r) {
    const toml::array* row = rows[r].as_array();
    if (row == nullptr || row->size() != n) {
      throw InputError(position_of(rows[r].source(), file), fmt::format("[covariance] matrix row {}: {} numbers needed", r + 1, n));
    }
    for (std::size_t k = 0; k < n; ++k) c(slot[r], slot[k]) = finite_number((*row)[k], file, "[covariance] entry");
  }
  for (Eigen::Index i = 0; i < c.rows(); ++i) {
    if (c(i, i) < 0.0)
      throw InputError(position_of(matrix->source(), file),
                       fmt::format("[covariance]: the variance of '{}' is negative", terms[std::size_t(i)].term.to_string()));
  }
  for (Eigen::Index i = 0; i < c.rows(); ++i) {
    for (Eigen::Index k = 0; k < i; ++k) {
      if (std::abs(c(i, k) - c(k, i)) > 1e-9 * std::sqrt(c(i, i) * c(k, k))) {
        throw InputError(position_of(matrix->source(), file),
                         fmt::format("[covariance] is not symmetric at '{}', '{}'", terms[std::size_t(i)].term.to_string(),
                                     terms[std::size_t(k)].term.to_string()));
      }
    }
  }
  return c;
}

// Shortest round-trip digits, with ".0" when they would otherwise read as a TOML integer.
std::string toml_float(double v, std::string_view what) {
  if (!std::isfinite(v)) throw InputError(fmt::format("cannot write model: {} = {} is not finite", what, v));
  return inertia::toml_float(v);
}

// [[a, b, c], [d, e, f], [g, h, i]]
std::string matrix_text(const frames::Dcm& m, std::string_view what) {
  std::string s = "[";
  for (int r = 0; r < 3; ++r) {
    s += r == 0 ? "[" : ", [";
    for (int c = 0; c < 3; ++c) s += (c == 0 ? "" : ", ") + toml_float(m(r, c), what);
    s += "]";
  }
  return s + "]";
}

}  // namespace

ModelFile parse_model(std::string_view text, const std::string& source_name) {
  toml::table root;
  try {
    root = toml::parse(text, std::string_view{source_name});
  } catch (const toml::parse_error& e) {
    throw InputError(position_of(e.source(), source_name), std::string(e.description()));
  }
  const std::string& file = source_name;
  ModelFile model;

  const toml::node* sensor = root.get("sensor");
  if (sensor == nullptr) throw InputError(SourcePosition{file, 0, 0}, "missing key 'sensor'");
  const auto sensor_text = sensor->value<std::string>();
  const auto kind = sensor->is_string() ? dataset::sensor_kind_from_string(*sensor_text) : std::nullopt;
  if (!kind) {
    throw InputError(position_of(sensor->source(), file), "sensor must be \"accelerometer\" or \"gyroscope\"");
  }
  model.sensor = *kind;

  if (const toml::node* m = root.get("m_cs")) {
    model.m_cs = rotation_at(*m, file, "m_cs");
  } else {
    throw InputError(SourcePosition{file, 0, 0}, "missing key 'm_cs' (M_C^S, 3x3)");
  }

  const toml::table* terms = optional_table(root, "terms", file);
  if (terms == nullptr || terms->empty()) {
    throw InputError(SourcePosition{file, 0, 0}, "missing or empty [terms] table (term = coefficient)");
  }
  std::vector<std::string> spelled;
  for (const auto& [key, node] : in_file_order(*terms)) {
    ident::Term term = term_at(*key, file, "terms");
    for (std::size_t j = 0; j < model.terms.size(); ++j) {
      if (model.terms[j].term == term) {
        throw InputError(position_of(key->source(), file),
                         fmt::format("[terms]: '{}' is the same term as '{}' ({})", key->str(), spelled[j],
                                     term.to_string()));
      }
    }
    const double value = finite_number(*node, file, fmt::format("coefficient of '{}'", key->str()));
    spelled.emplace_back(key->str());
    model.terms.push_back(ModelTerm{std::move(term), value, std::nullopt});
  }

  if (const toml::table* stds = optional_table(root, "std", file)) {
    for (const auto& [key, node] : in_file_order(*stds)) {
      const ident::Term term = term_at(*key, file, "std");
      const auto it = std::find_if(model.terms.begin(), model.terms.end(),
                                   [&](const ModelTerm& t) { return t.term == term; });
      if (it == model.terms.end()) {
        throw InputError(position_of(key->source(), file),
                         fmt::format("[std]: term '{}' is not in [terms]", key->str()));
      }
      const double sd = finite_number(*node, file, fmt::format("standard deviation of '{}'", key->str()));
      if (sd < 0.0) {
        throw InputError(position_of(node->source(), file), fmt::format("[std]: '{}' is negative", key->str()));
      }
      it->std = sd;
    }
  }

  if (const toml::node* at = root.get("covariance")) {
    const toml::table* table = optional_table(root, "covariance", file);
    model.covariance = read_covariance(*table, model.terms, file, *at);
  }
  if (const toml::table* range = optional_table(root, "range", file)) {
    for (const auto& [key, node] : in_file_order(*range)) {
      const ident::Variable v = range_variable(*key, file);
      const toml::array* span = node->as_array();
      if (span == nullptr || span->size() != 2)
        throw InputError(position_of(node->source(), file), fmt::format("[range] {} must be [lowest, highest]", key->str()));
      const double lo = finite_number((*span)[0], file, fmt::format("[range] {}", key->str()));
      const double hi = finite_number((*span)[1], file, fmt::format("[range] {}", key->str()));
      if (!(lo <= hi))
        throw InputError(position_of(node->source(), file), fmt::format("[range] {}: lowest {} above highest {}", key->str(), lo, hi));
      model.range[v] = ModelFile::Span{lo, hi};
    }
  }
  if (const toml::node* frames_node = root.get("case_frame")) {
    const toml::array* list = frames_node->as_array();
    if (list == nullptr || !list->is_array_of_tables())
      throw InputError(position_of(frames_node->source(), file), "'case_frame' must be [[case_frame]] tables");
    for (const toml::node& node : *list) {
      const toml::table& t = *node.as_table();
      const auto name = t.get("case") != nullptr ? t.get("case")->value<std::string>() : std::nullopt;
      const toml::node* m = t.get("m_es");
      if (!name || name->empty() || m == nullptr)
        throw InputError(position_of(node.source(), file), "[[case_frame]] needs 'case' (a name) and 'm_es'");
      for (const ModelFile::CaseFrame& other : model.case_frames) {
        if (other.case_name == *name)
          throw InputError(position_of(node.source(), file), fmt::format("[[case_frame]] '{}' given twice", *name));
      }
      model.case_frames.push_back({*name, rotation_at(*m, file, "m_es")});
    }
  }
  if (const toml::table* m = optional_table(root, "misalignment", file)) {
    ModelFile::Misalignment a;
    const auto number = [&](const char* key) {
      const toml::node* n = m->get(key);
      if (n == nullptr) throw InputError(position_of(m->source(), file), fmt::format("[misalignment] needs '{}'", key));
      return finite_number(*n, file, fmt::format("[misalignment] {}", key));
    };
    a.about_p = number("about_p");
    a.about_o = number("about_o");
    a.sd_p = number("sd_p");
    a.sd_o = number("sd_o");
    if (a.sd_p < 0.0 || a.sd_o < 0.0) throw InputError(position_of(m->source(), file), "[misalignment]: a negative sd");
    if (m->get("dof") != nullptr) {
      a.dof = number("dof");
      if (!(a.dof > 0.0)) throw InputError(position_of(m->source(), file), "[misalignment]: dof must be > 0");
    }
    model.misalignment = a;
  }
  if (const toml::table* u = optional_table(root, "undetermined", file)) {
    for (const auto& [key, node] : in_file_order(*u)) {
      if (!node->is_string()) throw InputError(position_of(node->source(), file), "[undetermined]: the reason must be a string");
      model.undetermined.emplace_back(std::string(key->str()), *node->value<std::string>());
    }
  }
  if (const toml::table* c = optional_table(root, "conditions", file)) {
    if (const toml::node* d = c->get("duration_s")) model.conditions.duration_s = finite_number(*d, file, "[conditions] duration_s");
    model.conditions.source = optional_string(*c, "source", file).value_or("");
    model.conditions.software = optional_string(*c, "software", file).value_or("");
    model.conditions.date = optional_string(*c, "date", file).value_or("");
    if (const toml::node* list = c->get("cases")) {
      const toml::array* a = list->as_array();
      if (a == nullptr) throw InputError(position_of(list->source(), file), "[conditions] cases must be an array of names");
      for (const toml::node& n : *a) {
        if (!n.is_string()) throw InputError(position_of(n.source(), file), "[conditions] cases must be names");
        model.conditions.cases.push_back(*n.value<std::string>());
      }
    }
  }
  model.name = optional_string(root, "sensor_name", file).value_or("");
  model.serial = optional_string(root, "serial", file).value_or("");
  model.part = optional_string(root, "part", file).value_or("");
  model.unit = optional_string(root, "unit", file).value_or("");
  if (!model.unit.empty()) {
    const std::string axis = optional_string(root, "unit_axis", file).value_or("");
    if (axis != "x" && axis != "y" && axis != "z")
      throw InputError(SourcePosition{file, 0, 0}, "unit_axis must be \"x\", \"y\" or \"z\" where unit is given");
    model.unit_axis = axis[0] - 'x';
  }
  model.output_unit = optional_string(root, "output_unit", file).value_or("");
  if (const toml::node* t = root.get("t_ref")) model.t_ref = finite_number(*t, file, "t_ref");
  model.sample_period_s = optional_positive(root, "sample_period_s", file);

  if (const toml::node* b = root.get("square_highpass_rad_s")) {
    model.square_highpass_rad_s = finite_number(*b, file, "square_highpass_rad_s");
    if (!(*model.square_highpass_rad_s > 0.0)) {
      throw InputError(position_of(b->source(), file), "square_highpass_rad_s must be positive");
    }
  }
  if (const toml::table* noise = optional_table(root, "noise", file)) {
    if (const toml::node* sd = noise->get("white_sd")) {
      model.white_sd = finite_number(*sd, file, "noise.white_sd");
      if (*model.white_sd < 0.0) {
        throw InputError(position_of(sd->source(), file), "noise.white_sd is negative");
      }
    }
    if (const toml::node* sd = noise->get("output_sd")) {
      model.output_sd = finite_number(*sd, file, "noise.output_sd");
      if (*model.output_sd < 0.0) throw InputError(position_of(sd->source(), file), "noise.output_sd is negative");
    }
    const toml::table* sd = optional_table(*noise, "std", file);
    for (std::size_t i = 0; i < ModelFile::NoiseTerms::kKeys.size(); ++i) {
      const char* key = ModelFile::NoiseTerms::kKeys[i];
      if (const toml::node* v = noise->get(key)) {
        std::optional<double>& slot = model.noise.values[i];
        slot = finite_number(*v, file, std::string("noise.") + key);
        if (*slot < 0.0) throw InputError(position_of(v->source(), file), std::string("noise.") + key + " is negative");
      }
      if (const toml::node* v = sd != nullptr ? sd->get(key) : nullptr) {
        const std::string name = std::string("noise.std.") + key;
        std::optional<double>& slot = model.noise.sd[i];
        slot = finite_number(*v, file, name);
        if (*slot < 0.0) throw InputError(position_of(v->source(), file), name + " is negative");
        if (!model.noise.values[i])
          throw InputError(position_of(v->source(), file), name + " is given but [noise] has no " + key);
      }
    }
  }
  return model;
}

ModelFile read_model(const std::filesystem::path& file) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(file.c_str(), "rb"), &std::fclose);
  if (!f) {
    throw InputError(SourcePosition{file.string(), 0, 0}, fmt::format("cannot open: {}", std::strerror(errno)));
  }
  std::string text;
  char chunk[1 << 14];
  std::size_t got = 0;
  while ((got = std::fread(chunk, 1, sizeof chunk, f.get())) > 0) text.append(chunk, got);
  return parse_model(text, file.string());
}

std::string format_model(const ModelFile& model) {
  std::string s = "sensor = " + toml_quote(dataset::to_string(model.sensor)) + "\n";
  if (!model.name.empty()) s += "sensor_name = " + toml_quote(model.name) + "\n";
  if (!model.serial.empty()) s += "serial = " + toml_quote(model.serial) + "\n";
  if (!model.part.empty()) s += "part = " + toml_quote(model.part) + "\n";
  if (!model.unit.empty() && model.unit_axis >= 0)
    s += "unit = " + toml_quote(model.unit) + "\nunit_axis = \"" + std::string(1, static_cast<char>('x' + model.unit_axis)) + "\"\n";
  if (!model.output_unit.empty()) s += "output_unit = " + toml_quote(model.output_unit) + "\n";
  if (model.t_ref) s += "t_ref = " + toml_float(*model.t_ref, "t_ref") + "\n";
  if (model.sample_period_s) s += "sample_period_s = " + toml_float(*model.sample_period_s, "sample_period_s") + "\n";
  s += "m_cs = " + matrix_text(model.m_cs, "m_cs") + "\n";
  if (model.square_highpass_rad_s) {
    s += "# a_i^2, a_p^2, a_o^2 act through the high pass s / (s + b) of eq. 12\n";
    s += "square_highpass_rad_s = " + toml_float(*model.square_highpass_rad_s, "square_highpass_rad_s") + "\n";
  }
  s += "\n[terms]\n";
  bool any_std = false;
  for (const ModelTerm& t : model.terms) {
    const std::string name = t.term.to_string();
    s += toml_quote(name) + " = " + toml_float(t.coefficient, name) + "\n";
    any_std = any_std || t.std.has_value();
  }
  if (any_std) {
    s += "\n[std]\n";
    for (const ModelTerm& t : model.terms) {
      if (t.std) s += toml_quote(t.term.to_string()) + " = " + toml_float(*t.std, "std") + "\n";
    }
  }
  if (model.covariance.size() > 0) {
    const auto n = static_cast<Eigen::Index>(model.terms.size());
    if (model.covariance.rows() != n || model.covariance.cols() != n)
      throw InputError(fmt::format("cannot write model: covariance is {}x{} for {} terms", model.covariance.rows(),
                                   model.covariance.cols(), n));
    s += "\n[covariance]\nterms = [";
    for (Eigen::Index i = 0; i < n; ++i) s += (i == 0 ? "" : ", ") + toml_quote(model.terms[std::size_t(i)].term.to_string());
    s += "]\nmatrix = [\n";
    for (Eigen::Index i = 0; i < n; ++i) {
      s += "  [";
      for (Eigen::Index k = 0; k < n; ++k) s += (k == 0 ? "" : ", ") + toml_float(model.covariance(i, k), "covariance");
      s += "],\n";
    }
    s += "]\n";
  }
  if (!model.range.empty()) {
    s += "\n[range]\n";
    for (const auto& [v, span] : model.range) {
      s += fmt::format("{} = [{}, {}]\n", ident::variable_name(v), toml_float(span.lowest, "range"),
                       toml_float(span.highest, "range"));
    }
  }
  if (model.misalignment) {
    const ModelFile::Misalignment& a = *model.misalignment;
    s += "\n[misalignment]\nabout_p = " + toml_float(a.about_p, "about_p") + "\nabout_o = " + toml_float(a.about_o, "about_o") +
         "\nsd_p = " + toml_float(a.sd_p, "sd_p") + "\nsd_o = " + toml_float(a.sd_o, "sd_o") + "\n";
    if (std::isfinite(a.dof)) s += "dof = " + toml_float(a.dof, "dof") + "\n";
  }
  if (!model.undetermined.empty()) {
    s += "\n[undetermined]\n";
    for (const auto& [term, reason] : model.undetermined) s += toml_quote(term) + " = " + toml_quote(reason) + "\n";
  }
  const ModelFile::Conditions& c = model.conditions;
  if (c.duration_s || !c.source.empty() || !c.software.empty() || !c.date.empty() || !c.cases.empty()) {
    s += "\n[conditions]\n";
    if (c.duration_s) s += "duration_s = " + toml_float(*c.duration_s, "duration_s") + "\n";
    if (!c.source.empty()) s += "source = " + toml_quote(c.source) + "\n";
    if (!c.cases.empty()) {
      s += "cases = [";
      for (std::size_t i = 0; i < c.cases.size(); ++i) s += (i ? ", " : "") + toml_quote(c.cases[i]);
      s += "]\n";
    }
    if (!c.software.empty()) s += "software = " + toml_quote(c.software) + "\n";
    if (!c.date.empty()) s += "date = " + toml_quote(c.date) + "\n";
  }
  for (const ModelFile::CaseFrame& f : model.case_frames) {
    s += "\n[[case_frame]]\ncase = " + toml_quote(f.case_name) + "\nm_es = " + matrix_text(f.m_es, "m_es") + "\n";
  }
  if (model.white_sd || model.output_sd || model.noise.any()) {
    s += "\n[noise]\n";
    if (model.white_sd) s += "white_sd = " + toml_float(*model.white_sd, "white_sd") + "\n";
    if (model.output_sd) s += "output_sd = " + toml_float(*model.output_sd, "output_sd") + "\n";
    for (std::size_t i = 0; i < ModelFile::NoiseTerms::kKeys.size(); ++i) {
      const char* key = ModelFile::NoiseTerms::kKeys[i];
      if (const std::optional<double>& v = model.noise.values[i]) s += std::string(key) + " = " + toml_float(*v, key) + "\n";
    }
    if (std::any_of(model.noise.sd.begin(), model.noise.sd.end(), [](const std::optional<double>& v) { return v.has_value(); })) {
      s += "\n[noise.std]\n";
      for (std::size_t i = 0; i < ModelFile::NoiseTerms::kKeys.size(); ++i) {
        const char* key = ModelFile::NoiseTerms::kKeys[i];
        if (const std::optional<double>& v = model.noise.sd[i]) s += std::string(key) + " = " + toml_float(*v, key) + "\n";
      }
    }
  }
  return s;
}

void write_model(const std::filesystem::path& file, const ModelFile& model) {
  write_file_atomically(file, format_model(model));
}

}  // namespace inertia::model
