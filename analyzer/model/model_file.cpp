#include "analyzer/model/model_file.hpp"
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


// Shortest round-trip digits, with ".0" when they would otherwise read as a TOML integer.
std::string toml_float(double v, std::string_view what) {
  if (!std::isfinite(v)) throw InputError(fmt::format("cannot write model: {} = {} is not finite", what, v));
  return inertia::toml_float(v);
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
    const toml::array* rows = m->as_array();
    const auto bad = [&](const toml::node& at) {
      return InputError(position_of(at.source(), file), "'m_cs' must be a 3x3 array of numbers, [[..], [..], [..]]");
    };
    if (rows == nullptr || rows->size() != 3) throw bad(*m);
    for (std::size_t r = 0; r < 3; ++r) {
      const toml::array* row = (*rows)[r].as_array();
      if (row == nullptr || row->size() != 3) throw bad((*rows)[r]);
      for (std::size_t c = 0; c < 3; ++c) {
        model.m_cs(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
            finite_number((*row)[c], file, "'m_cs' entry");
      }
    }
    if (!frames::is_rotation(model.m_cs, dataset::kRotationTolerance)) {
      throw InputError(position_of(m->source(), file),
                       fmt::format("m_cs is not a rotation (max |M M^T - I| = {:.3g}, det = {:.9g}, tolerance {})",
                                   (model.m_cs * model.m_cs.transpose() - frames::Dcm::Identity()).cwiseAbs().maxCoeff(),
                                   model.m_cs.determinant(), dataset::kRotationTolerance));
    }
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
  s += "m_cs = [";
  for (int r = 0; r < 3; ++r) {
    s += r == 0 ? "[" : ", [";
    for (int c = 0; c < 3; ++c) s += (c == 0 ? "" : ", ") + toml_float(model.m_cs(r, c), "m_cs");
    s += "]";
  }
  s += "]\n";
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
  if (model.white_sd || model.noise.any()) {
    s += "\n[noise]\n";
    if (model.white_sd) s += "white_sd = " + toml_float(*model.white_sd, "white_sd") + "\n";
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
  const std::string text = format_model(model);
  std::filesystem::path temporary = file;
  temporary += fmt::format(".partial-{}", ::getpid());
  {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(temporary.c_str(), "wb"), &std::fclose);
    if (!f) throw std::system_error(errno, std::generic_category(), "cannot open " + temporary.string() + " for writing");
    if (std::fwrite(text.data(), 1, text.size(), f.get()) != text.size() || std::fflush(f.get()) != 0 ||
        ::fsync(::fileno(f.get())) != 0) {
      const int error = errno;
      f.reset();
      std::filesystem::remove(temporary);
      throw std::system_error(error, std::generic_category(), "cannot write " + temporary.string());
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, file, error);
  if (error) {
    std::filesystem::remove(temporary);
    throw std::system_error(error, "cannot rename " + temporary.string() + " to " + file.string());
  }
}

}  // namespace inertia::model
