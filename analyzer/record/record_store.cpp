#include "analyzer/record/record_store.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <openssl/evp.h>

#include <boost/math/distributions/normal.hpp>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <fstream>
#include <memory>
#include <stdexcept>

#include "common/input_error.hpp"

namespace inertia::record {

namespace {

const char* status_text(report::SheetEntry::Status s) {
  switch (s) {
    case report::SheetEntry::Status::Determined: return "determined";
    case report::SheetEntry::Status::Undetermined: return "not determined";
    case report::SheetEntry::Status::NotSelected: return "not selected";
  }
  return "?";
}

std::string text(const Value& v) {
  const auto* s = std::get_if<std::string>(&v);
  return s != nullptr ? *s : std::string();
}
long long integer(const Value& v) {
  const auto* i = std::get_if<long long>(&v);
  return i != nullptr ? *i : 0;
}
std::optional<double> real(const Value& v) {
  if (const auto* d = std::get_if<double>(&v)) return *d;
  if (const auto* i = std::get_if<long long>(&v)) return static_cast<double>(*i);   // SQLite keeps an integral REAL as is
  return std::nullopt;
}
Value optional_real(bool present, double v) { return present && std::isfinite(v) ? Value(v) : Value(); }

}  // namespace

RecordStore::RecordStore(const std::string& location)
    : database_(is_postgresql_url(location) ? open_postgresql_record(location) : open_sqlite_record(location)) {}

bool is_postgresql_url(std::string_view location) {
  return location.starts_with("postgresql://") || location.starts_with("postgres://");
}

long long RecordStore::add(Characterization c) {
  c.recorded_utc = fmt::format("{:%Y-%m-%dT%H:%M:%SZ}", fmt::gmtime(std::time(nullptr)));
  database_->begin_write();
  try {
    const std::vector<Row> inserted = database_->query(
        "INSERT INTO characterization (recorded_utc, serial, sensor_name, sensor_kind, bench, operator, plan, software, input_path, "
        "input_sha256, model_toml, sheet_json, report_path, part, unit) VALUES ($1,$2,$3,$4,$5,$6,$7,$8,$9,$10,$11,$12,$13,$14,$15) "
        "RETURNING id",
        {c.recorded_utc, c.serial, c.sensor_name, c.sensor_kind, c.bench, c.operator_name, c.plan, c.software, c.input_path,
         c.input_sha256, c.model_toml, c.sheet_json, c.report_path, c.part, c.unit});
    c.id = integer(inserted.at(0).at(0));
    for (const report::SheetEntry& e : c.parameters) {
      const bool determined = e.status == report::SheetEntry::Status::Determined;
      database_->query("INSERT INTO parameter (characterization_id, name, unit, status, value, expanded_uncertainty) "
                       "VALUES ($1,$2,$3,$4,$5,$6)",
                       {c.id, e.name, e.unit, std::string(status_text(e.status)), optional_real(determined, e.value),
                        optional_real(determined, e.expanded_uncertainty)});
    }
    database_->commit();
  } catch (...) {
    database_->rollback();
    throw;
  }
  return c.id;
}

namespace {

/// The columns list() reads, then the long texts show() adds.
constexpr const char* kSummaryColumns =
    "id, recorded_utc, serial, sensor_name, sensor_kind, bench, operator, plan, software, input_path, input_sha256, report_path, "
    "part, unit";

Characterization characterization_from(const Row& r, bool with_texts) {
  Characterization c;
  c.id = integer(r[0]);
  std::string* fields[] = {&c.recorded_utc, &c.serial,     &c.sensor_name,  &c.sensor_kind, &c.bench, &c.operator_name,
                           &c.plan,         &c.software,   &c.input_path,   &c.input_sha256, &c.report_path, &c.part, &c.unit};
  std::size_t i = 1;
  for (std::string* f : fields) *f = text(r[i++]);
  if (with_texts) {
    c.model_toml = text(r[i++]);
    c.sheet_json = text(r[i++]);
  }
  return c;
}

}  // namespace

std::vector<Characterization> RecordStore::list(const std::string& serial) const {
  std::vector<Characterization> out;
  for (const Row& r : database_->query(fmt::format("SELECT {} FROM characterization WHERE $1 = '' OR serial = $1 ORDER BY id", kSummaryColumns),
                                       {serial}))
    out.push_back(characterization_from(r, false));
  return out;
}

std::optional<Characterization> RecordStore::show(long long id) const {
  const std::vector<Row> rows =
      database_->query(fmt::format("SELECT {}, model_toml, sheet_json FROM characterization WHERE id = $1", kSummaryColumns), {id});
  if (rows.empty()) return std::nullopt;
  return characterization_from(rows.front(), true);
}

std::vector<ParameterPoint> RecordStore::history(const std::string& serial, const std::string& parameter) const {
  std::vector<ParameterPoint> out;
  for (const Row& r : database_->query("SELECT c.id, c.recorded_utc, p.status, p.value, p.expanded_uncertainty, p.unit "
                                       "FROM characterization c JOIN parameter p ON p.characterization_id = c.id "
                                       "WHERE c.serial = $1 AND p.name = $2 ORDER BY c.id",
                                       {serial, parameter})) {
    ParameterPoint p;
    p.id = integer(r[0]);
    p.recorded_utc = text(r[1]);
    p.status = text(r[2]);
    p.value = real(r[3]);
    p.expanded_uncertainty = real(r[4]);
    p.unit = text(r[5]);
    out.push_back(std::move(p));
  }
  return out;
}

std::vector<PopulationValue> RecordStore::population(const std::string& sensor_kind, const std::string& part) const {
  std::vector<PopulationValue> out;
  for (const Row& r : database_->query("SELECT c.id, c.serial, p.name, p.unit, p.value, p.expanded_uncertainty "
                                       "FROM characterization c JOIN parameter p ON p.characterization_id = c.id "
                                       "WHERE c.id IN (SELECT max(id) FROM characterization WHERE sensor_kind = $1 AND part = $2 "
                                       "GROUP BY serial) AND p.value IS NOT NULL ORDER BY c.id, p.name",
                                       {sensor_kind, part})) {
    PopulationValue v;
    v.id = integer(r[0]);
    v.serial = text(r[1]);
    v.name = text(r[2]);
    v.unit = text(r[3]);
    v.value = real(r[4]).value_or(NAN);
    v.expanded_uncertainty = real(r[5]).value_or(NAN);
    out.push_back(std::move(v));
  }
  return out;
}

std::string input_sha256(const std::filesystem::path& input) {
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_directory(input)) {
    for (const auto& e : std::filesystem::directory_iterator(input)) {
      const std::string ext = e.path().extension().string();
      if (e.is_regular_file() && (ext == ".csv" || e.path().filename() == "dataset.toml")) files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
  } else {
    files.push_back(input);
  }
  std::unique_ptr<EVP_MD_CTX, void (*)(EVP_MD_CTX*)> ctx(EVP_MD_CTX_new(), &EVP_MD_CTX_free);
  EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr);
  std::vector<char> buffer(1 << 20);
  for (const auto& f : files) {
    if (files.size() > 1) {
      const std::string name = f.filename().string() + '\0';
      EVP_DigestUpdate(ctx.get(), name.data(), name.size());
    }
    std::ifstream in(f, std::ios::binary);
    if (!in) throw InputError(fmt::format("cannot read {} for its SHA-256", f.string()));
    while (in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      EVP_DigestUpdate(ctx.get(), buffer.data(), static_cast<std::size_t>(in.gcount()));
    }
  }
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(ctx.get(), digest, &length);
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) hex += fmt::format("{:02x}", digest[i]);
  return hex;
}

Drift find_drift(const std::vector<ParameterPoint>& points, double family_alpha) {
  std::vector<std::size_t> valued;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (points[i].value && points[i].expanded_uncertainty && *points[i].expanded_uncertainty > 0.0) valued.push_back(i);
  }
  Drift d;
  if (valued.size() < 2) return d;
  const double m = static_cast<double>(valued.size() - 1);
  d.en_threshold = boost::math::quantile(boost::math::normal(), 1.0 - family_alpha / (2.0 * m)) / 2.0;
  const ParameterPoint& first = points[valued.front()];
  for (std::size_t k = 1; k < valued.size(); ++k) {
    const ParameterPoint& p = points[valued[k]];
    if (normalized_error(*p.value, *p.expanded_uncertainty, *first.value, *first.expanded_uncertainty) > d.en_threshold) {
      d.first_flagged = valued[k];
      break;
    }
  }
  return d;
}

double normalized_error(double a, double ua, double b, double ub) { return std::abs(a - b) / std::sqrt(ua * ua + ub * ub); }

double percentile_rank(double value, const std::vector<double>& others) {
  if (others.empty()) return NAN;
  double below = 0.0;
  for (const double o : others) below += o < value ? 1.0 : (o == value ? 0.5 : 0.0);
  return 100.0 * below / static_cast<double>(others.size());
}

}  // namespace inertia::record
