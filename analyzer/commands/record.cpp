#include "analyzer/commands/record.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <pwd.h>
#include <unistd.h>

#include <cstdlib>

#include "analyzer/record/record_store.hpp"
#include "analyzer/report/parameter_sheet.hpp"
#include "common/input_error.hpp"

namespace inertia::commands {

namespace {

std::string login_name() {
  if (const char* sudo = std::getenv("SUDO_USER"); sudo != nullptr && *sudo != '\0') return sudo;
  if (const passwd* pw = ::getpwuid(::geteuid()); pw != nullptr) return pw->pw_name;
  return "unknown";
}

}  // namespace

long long record_characterization(const RecordRequest& request, const model::ModelFile& model) {
  record::RecordStore store(request.db);
  record::Characterization c;
  c.serial = request.serial.empty() ? model.name : request.serial;
  if (c.serial.empty()) throw InputError("--record: the model names no sensor; give --serial");
  c.sensor_name = model.name;
  c.sensor_kind = dataset::to_string(model.sensor);
  c.bench = request.bench;
  c.operator_name = request.operator_name.empty() ? login_name() : request.operator_name;
  c.plan = fmt::format("{}", fmt::join(model.conditions.cases, ", "));
  c.software = model.conditions.software;
  c.input_path = std::filesystem::absolute(request.input).string();
  c.input_sha256 = record::input_sha256(request.input);
  c.model_toml = model::format_model(model);
  const report::ParameterSheet sheet = report::parameter_sheet(model);
  c.sheet_json = report::sheet_json(sheet).dump();
  c.report_path = request.report_path.empty() ? std::string() : std::filesystem::absolute(request.report_path).string();
  c.parameters = sheet.entries;
  return store.add(std::move(c));
}

int run_record_list(const std::filesystem::path& db, const std::string& serial, std::ostream& out) {
  const record::RecordStore store(db);
  fmt::print(out, "{:>5}  {:<20}  {:<12} {:<10} {:<14} {:<10} {}\n", "id", "recorded (UTC)", "serial", "sensor", "kind", "operator",
             "input");
  for (const record::Characterization& c : store.list(serial)) {
    fmt::print(out, "{:>5}  {:<20}  {:<12} {:<10} {:<14} {:<10} {} (sha256 {}...)\n", c.id, c.recorded_utc, c.serial, c.sensor_name,
               c.sensor_kind, c.operator_name, c.input_path, c.input_sha256.substr(0, 12));
  }
  return kExitOk;
}

int run_record_show(const std::filesystem::path& db, long long id, std::ostream& out) {
  const record::RecordStore store(db);
  const std::optional<record::Characterization> c = store.show(id);
  if (!c) throw InputError(fmt::format("record database {} has no characterization {}", db.string(), id));
  fmt::print(out,
             "characterization {} recorded {}\nserial {}, sensor {} ({}), bench {}, operator {}\nplan: {}\nsoftware: {}\n"
             "input: {} (sha256 {})\nreport: {}\n\nmodel:\n{}\nsheet: {}\n",
             c->id, c->recorded_utc, c->serial, c->sensor_name, c->sensor_kind, c->bench.empty() ? "(not stated)" : c->bench,
             c->operator_name, c->plan, c->software, c->input_path, c->input_sha256, c->report_path.empty() ? "-" : c->report_path,
             c->model_toml, c->sheet_json);
  return kExitOk;
}

int run_record_history(const std::filesystem::path& db, const std::string& serial, const std::string& parameter, std::ostream& out) {
  const record::RecordStore store(db);
  const std::vector<record::ParameterPoint> points = store.history(serial, parameter);
  if (points.empty())
    throw InputError(fmt::format("record database {} holds no '{}' of serial '{}'", db.string(), parameter, serial));
  fmt::print(out,
             "{} of {} ({}), expanded uncertainty U (k = 2); En = |change| / sqrt(U1^2 + U2^2), against the one before and "
             "against the first\n",
             parameter, serial, points.front().unit);
  fmt::print(out, "{:>5}  {:<20}  {:>14}  {:>12}  {:>16}  {:>16}\n", "id", "recorded (UTC)", "value", "U", "En (previous)", "En (first)");
  const record::ParameterPoint* previous = nullptr;
  const record::ParameterPoint* first = nullptr;
  int flagged = 0;
  for (const record::ParameterPoint& p : points) {
    if (!p.value) {
      fmt::print(out, "{:>5}  {:<20}  {:>14}\n", p.id, p.recorded_utc, p.status);
      continue;
    }
    const auto en = [&](const record::ParameterPoint* before) -> std::string {
      if (before == nullptr || !before->expanded_uncertainty || !p.expanded_uncertainty) return "-";
      const double e = record::normalized_error(*p.value, *p.expanded_uncertainty, *before->value, *before->expanded_uncertainty);
      flagged += e > 1.0;
      return fmt::format("{:.2f}{}", e, e > 1.0 ? " changed" : "");
    };
    const std::string against_previous = en(previous), against_first = previous == first ? std::string("-") : en(first);
    fmt::print(out, "{:>5}  {:<20}  {:>14.6g}  {:>12.3g}  {:>16}  {:>16}\n", p.id, p.recorded_utc, *p.value,
               p.expanded_uncertainty.value_or(NAN), against_previous, against_first);
    if (first == nullptr) first = &p;
    previous = &p;
  }
  fmt::print(out, "{} comparison(s) with a change larger than the combined uncertainty (En > 1)\n", flagged);
  const record::Drift drift = record::find_drift(points);
  if (drift.first_flagged) {
    fmt::print(out, "drift: characterization {} differs from the first beyond chance at the family-wise 5 % level over the "
                    "history's comparisons (En > {:.2f})\n",
               points[*drift.first_flagged].id, drift.en_threshold);
  } else {
    fmt::print(out, "no drift at the family-wise 5 % level over the history's comparisons with the first (En > {:.2f} needed)\n",
               drift.en_threshold);
  }
  return kExitOk;
}

}  // namespace inertia::commands
