#include "analyzer/record/record_store.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <openssl/evp.h>
#include <sqlite3.h>

#include <boost/math/distributions/normal.hpp>

#include <algorithm>
#include <chrono>
#include <functional>
#include <thread>
#include <cmath>
#include <ctime>
#include <fstream>
#include <memory>
#include <stdexcept>

#include "common/input_error.hpp"

namespace inertia::record {

namespace {

constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS characterization (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  recorded_utc TEXT NOT NULL,
  serial TEXT NOT NULL,
  sensor_name TEXT NOT NULL,
  sensor_kind TEXT NOT NULL,
  bench TEXT NOT NULL,
  operator TEXT NOT NULL,
  plan TEXT NOT NULL,
  software TEXT NOT NULL,
  input_path TEXT NOT NULL,
  input_sha256 TEXT NOT NULL,
  model_toml TEXT NOT NULL,
  sheet_json TEXT NOT NULL,
  report_path TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS characterization_serial ON characterization(serial);
CREATE TABLE IF NOT EXISTS parameter (
  characterization_id INTEGER NOT NULL REFERENCES characterization(id),
  name TEXT NOT NULL,
  unit TEXT NOT NULL,
  status TEXT NOT NULL,
  value REAL,
  expanded_uncertainty REAL,
  PRIMARY KEY (characterization_id, name)
);
CREATE TRIGGER IF NOT EXISTS characterization_append_only_update BEFORE UPDATE ON characterization
  BEGIN SELECT RAISE(ABORT, 'the record is append-only'); END;
CREATE TRIGGER IF NOT EXISTS characterization_append_only_delete BEFORE DELETE ON characterization
  BEGIN SELECT RAISE(ABORT, 'the record is append-only'); END;
CREATE TRIGGER IF NOT EXISTS parameter_append_only_update BEFORE UPDATE ON parameter
  BEGIN SELECT RAISE(ABORT, 'the record is append-only'); END;
CREATE TRIGGER IF NOT EXISTS parameter_append_only_delete BEFORE DELETE ON parameter
  BEGIN SELECT RAISE(ABORT, 'the record is append-only'); END;
)sql";

struct Statement {
  sqlite3_stmt* s = nullptr;
  Statement(sqlite3* db, const char* sql) {
    if (sqlite3_prepare_v2(db, sql, -1, &s, nullptr) != SQLITE_OK) throw std::runtime_error(std::string("sqlite: ") + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(s); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  void text(int i, const std::string& v) { sqlite3_bind_text(s, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT); }
  void real(int i, std::optional<double> v) {
    if (v && std::isfinite(*v)) sqlite3_bind_double(s, i, *v);
    else sqlite3_bind_null(s, i);
  }
  [[nodiscard]] std::string column_text(int i) const {
    const auto* p = sqlite3_column_text(s, i);
    return p == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(p));
  }
  [[nodiscard]] std::optional<double> column_real(int i) const {
    if (sqlite3_column_type(s, i) == SQLITE_NULL) return std::nullopt;
    return sqlite3_column_double(s, i);
  }
};

const char* status_text(report::SheetEntry::Status s) {
  switch (s) {
    case report::SheetEntry::Status::Determined: return "determined";
    case report::SheetEntry::Status::Undetermined: return "not determined";
    case report::SheetEntry::Status::NotSelected: return "not selected";
  }
  return "?";
}

}  // namespace

RecordStore::RecordStore(const std::filesystem::path& file) : file_(file) {
  if (!file.parent_path().empty()) std::filesystem::create_directories(file.parent_path());
  if (sqlite3_open_v2(file.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK) {
    const std::string why = db_ != nullptr ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw InputError(fmt::format("record database {}: cannot open: {}", file.string(), why));
  }
  sqlite3_busy_timeout(db_, 30000);
  // The first read tells a damaged file or another kind of file from a database: nothing has been
  // written to it yet.
  int version = 0;
  {
    sqlite3_stmt* s = nullptr;
    int rc = sqlite3_prepare_v2(db_, "PRAGMA user_version", -1, &s, nullptr);
    if (rc == SQLITE_OK) rc = sqlite3_step(s);
    if (rc == SQLITE_ROW) version = sqlite3_column_int(s, 0);
    const std::string why = sqlite3_errmsg(db_);
    sqlite3_finalize(s);
    if (rc != SQLITE_ROW) {
      sqlite3_close(db_);
      db_ = nullptr;
      throw InputError(fmt::format("record database {} is damaged or not an SQLite database ({}); nothing was written to it",
                                   file.string(), why));
    }
  }
  if (version > kSchemaVersion) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw InputError(fmt::format("record database {} has schema version {}, newer than this program's {}: refused, nothing "
                                 "written (use the newer inertia that wrote it)",
                                 file.string(), version, kSchemaVersion));
  }
  {
    char* error = nullptr;
    if (sqlite3_exec(db_, "PRAGMA quick_check", nullptr, nullptr, &error) != SQLITE_OK) {
      const std::string why = error != nullptr ? error : "";
      sqlite3_free(error);
      sqlite3_close(db_);
      db_ = nullptr;
      throw InputError(fmt::format("record database {} is damaged ({}); nothing was written to it", file.string(), why));
    }
  }
  // Switching to the write-ahead log takes the file for a moment, and SQLite does not wait for
  // it through the busy handler: two first writers at once retry until the other has done.
  const auto when_free = [this](const std::function<int()>& step) {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    for (;;) {
      const int rc = step();
      if ((rc != SQLITE_BUSY && rc != SQLITE_LOCKED) || std::chrono::steady_clock::now() > give_up) return rc;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  };
  const auto exec = [this](const std::string& sql) { return sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr); };
  if (when_free([&] { return exec("PRAGMA journal_mode=WAL"); }) != SQLITE_OK) execute("PRAGMA journal_mode=WAL");
  execute("PRAGMA foreign_keys=ON");
  if (version < kSchemaVersion) {
    // Migration: version 0 (a new file) to 1 creates the tables (idempotent, so a writer that
    // raced another to it does no harm); later versions add their steps here.
    if (when_free([&] { return exec("BEGIN IMMEDIATE"); }) != SQLITE_OK) execute("BEGIN IMMEDIATE");
    try {
      execute(kSchema);
      execute(fmt::format("PRAGMA user_version = {}", kSchemaVersion).c_str());
      execute("COMMIT");
    } catch (...) {
      sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
      throw;
    }
  }
}

RecordStore::~RecordStore() { sqlite3_close(db_); }

void RecordStore::execute(const char* sql) const {
  char* error = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string why = error != nullptr ? error : sqlite3_errmsg(db_);
    sqlite3_free(error);
    throw std::runtime_error(fmt::format("record database {}: {}", file_.string(), why));
  }
}

long long RecordStore::add(Characterization c) {
  c.recorded_utc = fmt::format("{:%Y-%m-%dT%H:%M:%SZ}", fmt::gmtime(std::time(nullptr)));
  execute("BEGIN IMMEDIATE");
  try {
    Statement insert(db_,
                     "INSERT INTO characterization (recorded_utc, serial, sensor_name, sensor_kind, bench, operator, plan, software, "
                     "input_path, input_sha256, model_toml, sheet_json, report_path) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?)");
    int i = 1;
    for (const std::string* v : {&c.recorded_utc, &c.serial, &c.sensor_name, &c.sensor_kind, &c.bench, &c.operator_name, &c.plan,
                                 &c.software, &c.input_path, &c.input_sha256, &c.model_toml, &c.sheet_json, &c.report_path})
      insert.text(i++, *v);
    if (sqlite3_step(insert.s) != SQLITE_DONE) throw std::runtime_error(std::string("sqlite: ") + sqlite3_errmsg(db_));
    c.id = sqlite3_last_insert_rowid(db_);
    Statement parameter(db_, "INSERT INTO parameter VALUES (?,?,?,?,?,?)");
    for (const report::SheetEntry& e : c.parameters) {
      sqlite3_reset(parameter.s);
      sqlite3_bind_int64(parameter.s, 1, c.id);
      parameter.text(2, e.name);
      parameter.text(3, e.unit);
      parameter.text(4, status_text(e.status));
      const bool determined = e.status == report::SheetEntry::Status::Determined;
      parameter.real(5, determined ? std::optional<double>(e.value) : std::nullopt);
      parameter.real(6, determined ? std::optional<double>(e.expanded_uncertainty) : std::nullopt);
      if (sqlite3_step(parameter.s) != SQLITE_DONE) throw std::runtime_error(std::string("sqlite: ") + sqlite3_errmsg(db_));
    }
    execute("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
  return c.id;
}

std::vector<Characterization> RecordStore::list(const std::string& serial) const {
  Statement q(db_,
              "SELECT id, recorded_utc, serial, sensor_name, sensor_kind, bench, operator, plan, software, input_path, input_sha256, "
              "report_path FROM characterization WHERE ?1 = '' OR serial = ?1 ORDER BY id");
  q.text(1, serial);
  std::vector<Characterization> out;
  while (sqlite3_step(q.s) == SQLITE_ROW) {
    Characterization c;
    c.id = sqlite3_column_int64(q.s, 0);
    c.recorded_utc = q.column_text(1);
    c.serial = q.column_text(2);
    c.sensor_name = q.column_text(3);
    c.sensor_kind = q.column_text(4);
    c.bench = q.column_text(5);
    c.operator_name = q.column_text(6);
    c.plan = q.column_text(7);
    c.software = q.column_text(8);
    c.input_path = q.column_text(9);
    c.input_sha256 = q.column_text(10);
    c.report_path = q.column_text(11);
    out.push_back(std::move(c));
  }
  return out;
}

std::optional<Characterization> RecordStore::show(long long id) const {
  Statement q(db_, "SELECT serial, sensor_name, sensor_kind, bench, operator, plan, software, input_path, input_sha256, model_toml, "
                   "sheet_json, report_path, recorded_utc FROM characterization WHERE id = ?");
  sqlite3_bind_int64(q.s, 1, id);
  if (sqlite3_step(q.s) != SQLITE_ROW) return std::nullopt;
  Characterization c;
  c.id = id;
  std::string* fields[] = {&c.serial,   &c.sensor_name, &c.sensor_kind,  &c.bench,      &c.operator_name, &c.plan,        &c.software,
                           &c.input_path, &c.input_sha256, &c.model_toml, &c.sheet_json, &c.report_path,   &c.recorded_utc};
  for (int i = 0; i < 13; ++i) *fields[i] = q.column_text(i);
  return c;
}

std::vector<ParameterPoint> RecordStore::history(const std::string& serial, const std::string& parameter) const {
  Statement q(db_, "SELECT c.id, c.recorded_utc, p.status, p.value, p.expanded_uncertainty, p.unit FROM characterization c JOIN parameter p "
                   "ON p.characterization_id = c.id WHERE c.serial = ? AND p.name = ? ORDER BY c.id");
  q.text(1, serial);
  q.text(2, parameter);
  std::vector<ParameterPoint> out;
  while (sqlite3_step(q.s) == SQLITE_ROW) {
    ParameterPoint p;
    p.id = sqlite3_column_int64(q.s, 0);
    p.recorded_utc = q.column_text(1);
    p.status = q.column_text(2);
    p.value = q.column_real(3);
    p.expanded_uncertainty = q.column_real(4);
    p.unit = q.column_text(5);
    out.push_back(std::move(p));
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

}  // namespace inertia::record
