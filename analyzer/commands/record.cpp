#include "analyzer/commands/record.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <pwd.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <set>

#include "analyzer/record/record_store.hpp"
#include "analyzer/report/gnuplot.hpp"
#include "analyzer/report/parameter_sheet.hpp"
#include "common/atomic_file.hpp"
#include "common/input_error.hpp"

namespace inertia::commands {

namespace {

std::string login_name() {
  if (const char* sudo = std::getenv("SUDO_USER"); sudo != nullptr && *sudo != '\0') return sudo;
  if (const passwd* pw = ::getpwuid(::geteuid()); pw != nullptr) return pw->pw_name;
  return "unknown";
}

}  // namespace

long long record_characterization(record::RecordStore& store, const RecordRequest& request, const model::ModelFile& model) {
  record::Characterization c;
  c.serial = model.serial.empty() ? model.name : model.serial;
  if (c.serial.empty()) throw InputError("--record: the model names no sensor; give --serial");
  c.part = model.part;
  c.unit = model.unit;
  c.sensor_name = model.name;
  c.sensor_kind = dataset::to_string(model.sensor);
  c.bench = request.bench;
  c.operator_name = request.operator_name.empty() ? login_name() : request.operator_name;
  c.plan = fmt::format("{}", fmt::join(model.conditions.cases, ", "));
  c.software = model.conditions.software;
  c.input_path = std::filesystem::absolute(request.input).string();
  c.input_sha256 = record::input_sha256(request.input);
  c.model_toml = model::format_model(model);
  const report::ParameterSheet sheet = request.sheet != nullptr ? *request.sheet : report::parameter_sheet(model);
  c.sheet_json = report::sheet_json(sheet).dump();
  c.report_path = request.report_path.empty() ? std::string() : std::filesystem::absolute(request.report_path).string();
  c.parameters = sheet.entries;
  return store.add(std::move(c));
}

int run_record_list(const std::string& db, const std::string& serial, std::ostream& out) {
  const record::RecordStore store(db);
  fmt::print(out, "{:>5}  {:<20}  {:<12} {:<12} {:<10} {:<14} {:<10} {}\n", "id", "recorded (UTC)", "serial", "part", "sensor", "kind",
             "operator", "input");
  for (const record::Characterization& c : store.list(serial)) {
    fmt::print(out, "{:>5}  {:<20}  {:<12} {:<12} {:<10} {:<14} {:<10} {} (sha256 {}...)\n", c.id, c.recorded_utc, c.serial,
               c.part.empty() ? "-" : c.part, c.sensor_name, c.sensor_kind, c.operator_name, c.input_path, c.input_sha256.substr(0, 12));
  }
  return kExitOk;
}

int run_record_show(const std::string& db, long long id, std::ostream& out) {
  const record::RecordStore store(db);
  const std::optional<record::Characterization> c = store.show(id);
  if (!c) throw InputError(fmt::format("{} has no characterization {}", store.describe(), id));
  fmt::print(out,
             "characterization {} recorded {}\nserial {}, part {}, sensor {} ({}{}), bench {}, operator {}\nplan: {}\nsoftware: {}\n"
             "input: {} (sha256 {})\nreport: {}\n\nmodel:\n{}\nsheet: {}\n",
             c->id, c->recorded_utc, c->serial, c->part.empty() ? "(not stated)" : c->part, c->sensor_name,
             c->sensor_kind, c->unit.empty() ? std::string() : ", in unit " + c->unit, c->bench.empty() ? "(not stated)" : c->bench,
             c->operator_name, c->plan, c->software, c->input_path, c->input_sha256, c->report_path.empty() ? "-" : c->report_path,
             c->model_toml, c->sheet_json);
  return kExitOk;
}

namespace {

/// The history as an SVG: each characterization's value with its expanded uncertainty as an error
/// bar, in record order, the first one's value and interval as a band, and the drift (if any)
/// from its first flagged characterization on in another colour. False when gnuplot cannot draw.
bool write_history_plot(const std::vector<record::ParameterPoint>& points, const record::Drift& drift, const std::string& title,
                        const std::filesystem::path& file) {
  const record::ParameterPoint* first = nullptr;
  std::string data;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const record::ParameterPoint& p = points[i];
    if (!p.value || !p.expanded_uncertainty) continue;
    if (first == nullptr) first = &p;
    const bool drifted = drift.first_flagged && i >= *drift.first_flagged;
    data += fmt::format("{} {:.17g} {:.17g} {} \"{} #{}\"\n", i + 1, *p.value, *p.expanded_uncertainty, drifted ? 1 : 0,
                        p.recorded_utc.substr(0, 10), p.id);
  }
  if (first == nullptr) return false;
  const report::ScratchDirectory scratch("inertia-history");
  const std::filesystem::path data_file = scratch.path() / "history.dat";
  write_file_atomically(data_file, data);
  const double lo = *first->value - *first->expanded_uncertainty, hi = *first->value + *first->expanded_uncertainty;
  const std::string script = fmt::format(
      "set title {}\nset ylabel {}\nset xlabel 'characterization (date, record id)'\nset grid\nset key top left\n"
      "set xrange [0.5:{}.5]\nset xtics rotate by -30\nset offsets 0, 0, graph 0.05, graph 0.05\n"
      "plot {:.17g} with lines lc rgb '#999999' dt 2 title 'the first +- U', {:.17g} with lines lc rgb '#999999' dt 2 notitle, "
      "{} using 1:($4 == 0 ? $2 : 1/0):3:xtic(5) with yerrorbars pt 7 lc rgb '#1f4e9c' title 'value, +- U (k = 2)', "
      "'' using 1:($4 == 1 ? $2 : 1/0):3 with yerrorbars pt 7 lc rgb '#c0392b' title 'drift (family-wise 5 %)'\n",
      report::gnuplot_quoted(title), report::gnuplot_quoted(points.front().unit), points.size(), lo, hi,
      report::gnuplot_quoted(data_file.string()));
  const std::optional<std::string> svg = report::gnuplot_svg(script, scratch.path());
  if (!svg) return false;
  write_file_atomically(file, "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n" + *svg);
  return true;
}

}  // namespace

int run_record_history(const std::string& db, const std::string& serial, const std::string& parameter, std::ostream& out,
                       const std::filesystem::path& plot) {
  const record::RecordStore store(db);
  const std::vector<record::ParameterPoint> points = store.history(serial, parameter);
  if (points.empty())
    throw InputError(fmt::format("{} holds no '{}' of serial '{}'", store.describe(), parameter, serial));
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
  if (drift.en_threshold == 0.0) {
    fmt::print(out, "fewer than two characterizations with a value: no drift can be judged yet\n");
  } else if (drift.first_flagged) {
    fmt::print(out, "drift: characterization {} differs from the first beyond chance at the family-wise 5 % level over the "
                    "history's comparisons (En > {:.2f})\n",
               points[*drift.first_flagged].id, drift.en_threshold);
  } else {
    fmt::print(out, "no drift at the family-wise 5 % level over the history's comparisons with the first (En > {:.2f} needed)\n",
               drift.en_threshold);
  }
  if (!plot.empty()) {
    if (!write_history_plot(points, drift, fmt::format("{} of {}", parameter, serial), plot)) {
      fmt::print(out, "plot not drawn: gnuplot is not installed or failed, or no characterization has a value\n");
      return kExitFailure;
    }
    fmt::print(out, "wrote {}\n", plot.string());
  }
  return kExitOk;
}

int run_record_compare(const std::string& db, const std::string& serial, std::ostream& out) {
  const record::RecordStore store(db);
  const std::vector<record::Characterization> own = store.list(serial);
  if (own.empty()) throw InputError(fmt::format("{} holds no characterization of serial '{}'", store.describe(), serial));
  const record::Characterization& latest = own.back();
  const std::vector<record::PopulationValue> population = store.population(latest.sensor_kind, latest.part);
  std::set<std::string> others;
  for (const record::PopulationValue& v : population) {
    if (v.serial != serial) others.insert(v.serial);
  }
  fmt::print(out, "serial {} (characterization {}, {}, part {}) against the latest characterization of each other serial of that "
                  "kind and part in {}: {} serial(s)\n",
             serial, latest.id, latest.sensor_kind, latest.part.empty() ? "not stated, so the population is the serials recorded without one" : latest.part,
             store.describe(), others.size());
  if (others.empty()) {
    fmt::print(out, "nothing to compare with: no other serial of this kind and part is recorded\n");
    return kExitOk;
  }
  fmt::print(out, "{:<48} {:>12} {:>10} {:<12} {:>4} {:>12} {:>27} {:>11}\n", "parameter", "value", "U (k = 2)", "unit", "n", "median",
             "population range", "percentile");
  std::size_t fewest = others.size();
  for (const record::PopulationValue& mine : population) {
    if (mine.id != latest.id) continue;
    std::vector<double> values;
    for (const record::PopulationValue& v : population) {
      if (v.serial != serial && v.name == mine.name && v.unit == mine.unit) values.push_back(v.value);
    }
    if (values.empty()) {
      fmt::print(out, "{:<48} {:>12.5g} {:>10.3g} {:<12} no other serial has it determined\n", mine.name, mine.value,
                 mine.expanded_uncertainty, mine.unit);
      continue;
    }
    fewest = std::min(fewest, values.size());
    std::sort(values.begin(), values.end());
    const std::size_t n = values.size();
    const double median = n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
    const double percentile = record::percentile_rank(mine.value, values);
    const char* edge = mine.value < values.front() ? " lowest" : (mine.value > values.back() ? " highest" : "");
    fmt::print(out, "{:<48} {:>12.5g} {:>10.3g} {:<12} {:>4} {:>12.5g} {:>27} {:>10.0f}%{}\n", mine.name, mine.value,
               mine.expanded_uncertainty, mine.unit, n, median, fmt::format("[{:.5g}, {:.5g}]", values.front(), values.back()),
               percentile, edge);
  }
  fmt::print(out, "percentile: the share of the other serials below this one (a tie counts half); with n others it moves in steps of "
                  "100/n %{}\n",
             fewest < 10 ? fmt::format(", so with as few as {} it says little", fewest) : std::string());
  return kExitOk;
}

}  // namespace inertia::commands
