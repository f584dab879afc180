// The record on a PostgreSQL server, for a lab whose bench PCs share one record: the same tables
// as the SQLite file, its schema version in the table inertia_record_schema, UPDATE, DELETE and
// TRUNCATE refused by triggers, migration under an advisory lock so that two first writers do not
// both migrate. The server keeps each transaction whole: a writer killed mid-record leaves none
// of it, since a connection that drops rolls back what it had not committed.
#include <fmt/format.h>
#include <libpq-fe.h>

#include <cmath>
#include <cstdlib>
#include <memory>
#include <regex>
#include <stdexcept>

#include "analyzer/record/record_database.hpp"
#include "common/input_error.hpp"

namespace inertia::record {

namespace {

/// Migration steps: kPostgresqlMigrations[k] takes the record from schema version k to k + 1.
constexpr const char* kPostgresqlMigrations[] = {
    R"sql(
CREATE TABLE IF NOT EXISTS characterization (
  id BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
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
  characterization_id BIGINT NOT NULL REFERENCES characterization(id),
  name TEXT NOT NULL,
  unit TEXT NOT NULL,
  status TEXT NOT NULL,
  value DOUBLE PRECISION,
  expanded_uncertainty DOUBLE PRECISION,
  PRIMARY KEY (characterization_id, name)
);
CREATE OR REPLACE FUNCTION inertia_record_append_only() RETURNS trigger LANGUAGE plpgsql AS
  $$ BEGIN RAISE EXCEPTION 'the record is append-only'; END $$;
CREATE OR REPLACE TRIGGER characterization_append_only BEFORE UPDATE OR DELETE OR TRUNCATE ON characterization
  FOR EACH STATEMENT EXECUTE FUNCTION inertia_record_append_only();
CREATE OR REPLACE TRIGGER parameter_append_only BEFORE UPDATE OR DELETE OR TRUNCATE ON parameter
  FOR EACH STATEMENT EXECUTE FUNCTION inertia_record_append_only();
)sql",
    R"sql(
ALTER TABLE characterization ADD COLUMN IF NOT EXISTS part TEXT NOT NULL DEFAULT '';
ALTER TABLE characterization ADD COLUMN IF NOT EXISTS unit TEXT NOT NULL DEFAULT '';
CREATE INDEX IF NOT EXISTS characterization_part ON characterization(sensor_kind, part);
)sql",
};
static_assert(std::size(kPostgresqlMigrations) == kSchemaVersion);

/// The advisory lock that serializes migrations (any constant, the same in every inertia).
constexpr long long kMigrationLock = 0x696e657274696131;   // "inertia1"

// Column types of the results we read (pg_type.h's OIDs, which libpq-dev does not install).
constexpr Oid kInt2 = 21, kInt4 = 23, kInt8 = 20, kFloat4 = 700, kFloat8 = 701, kNumeric = 1700;

/// `url` with any password replaced by ***, for messages.
std::string without_password(const std::string& url) {
  static const std::regex user_password(R"((://[^:/@?]*):[^@/?]*@)");
  static const std::regex password_option(R"(([?&]password=)[^&]*)");
  return std::regex_replace(std::regex_replace(url, user_password, "$1:***@"), password_option, "$1***");
}

class PostgresqlRecordDatabase final : public RecordDatabase {
 public:
  explicit PostgresqlRecordDatabase(const std::string& url) : where_(without_password(url)) {
    connection_.reset(PQconnectdb(url.c_str()));
    if (connection_ == nullptr || PQstatus(connection_.get()) != CONNECTION_OK) {
      const std::string why = connection_ != nullptr ? PQerrorMessage(connection_.get()) : "out of memory";
      throw InputError(fmt::format("{}: cannot connect: {}", describe(), trimmed(why)));
    }
    PQsetNoticeProcessor(connection_.get(), [](void*, const char*) {}, nullptr);   // "already exists, skipping"
    int version = read_version();
    refuse_newer(version);
    if (version < kSchemaVersion) {
      begin_write();
      try {
        query("SELECT pg_advisory_xact_lock($1)", {kMigrationLock});
        execute("CREATE TABLE IF NOT EXISTS inertia_record_schema (version INTEGER NOT NULL)");
        version = read_version();   // another writer may have migrated meanwhile
        refuse_newer(version);
        for (int step = version; step < kSchemaVersion; ++step) execute(kPostgresqlMigrations[step]);
        execute("DELETE FROM inertia_record_schema");
        query("INSERT INTO inertia_record_schema (version) VALUES ($1)", {static_cast<long long>(kSchemaVersion)});
        commit();
      } catch (...) {
        rollback();
        throw;
      }
    }
  }

  std::vector<Row> query(std::string_view sql, const std::vector<Value>& parameters) override {
    std::vector<std::string> texts(parameters.size());
    std::vector<const char*> values(parameters.size(), nullptr);
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      const Value& v = parameters[i];
      if (const auto* text = std::get_if<std::string>(&v)) texts[i] = *text;
      else if (const auto* real = std::get_if<double>(&v); real != nullptr && std::isfinite(*real)) texts[i] = fmt::format("{}", *real);
      else if (const auto* integer = std::get_if<long long>(&v)) texts[i] = std::to_string(*integer);
      else continue;   // NULL
      values[i] = texts[i].c_str();
    }
    const std::string statement(sql);
    const Result result(PQexecParams(connection_.get(), statement.c_str(), static_cast<int>(parameters.size()), nullptr,
                                     values.data(), nullptr, nullptr, 0));
    check(result.get());
    std::vector<Row> rows;
    const int columns = PQnfields(result.get());
    for (int r = 0; r < PQntuples(result.get()); ++r) {
      Row row(static_cast<std::size_t>(columns));
      for (int c = 0; c < columns; ++c) {
        if (PQgetisnull(result.get(), r, c) != 0) continue;
        const char* text = PQgetvalue(result.get(), r, c);
        switch (PQftype(result.get(), c)) {
          case kInt2: case kInt4: case kInt8: row[c] = std::strtoll(text, nullptr, 10); break;
          // PostgreSQL 12 and later print a float8 in its shortest exact form: strtod round-trips it.
          case kFloat4: case kFloat8: case kNumeric: row[c] = std::strtod(text, nullptr); break;
          default: row[c] = std::string(text, static_cast<std::size_t>(PQgetlength(result.get(), r, c)));
        }
      }
      rows.push_back(std::move(row));
    }
    return rows;
  }
  void begin_write() override { execute("BEGIN"); }
  void commit() override { execute("COMMIT"); }
  void rollback() noexcept override { PQclear(PQexec(connection_.get(), "ROLLBACK")); }
  [[nodiscard]] std::string describe() const override { return "record database " + where_; }

 private:
  struct ClearResult {
    void operator()(PGresult* r) const { PQclear(r); }
  };
  struct Finish {
    void operator()(PGconn* c) const { PQfinish(c); }
  };
  using Result = std::unique_ptr<PGresult, ClearResult>;

  static std::string trimmed(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    return s;
  }
  void check(const PGresult* r) const {
    const ExecStatusType status = PQresultStatus(r);
    if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) return;
    const std::string why = r != nullptr ? PQresultErrorMessage(r) : PQerrorMessage(connection_.get());
    throw std::runtime_error(fmt::format("{}: {}", describe(), trimmed(why)));
  }
  void execute(const char* sql) {
    const Result result(PQexec(connection_.get(), sql));
    check(result.get());
  }
  int read_version() {
    const std::vector<Row> exists = query("SELECT to_regclass('inertia_record_schema') IS NOT NULL", {});
    if (std::get<std::string>(exists.front().front()) != "t") return 0;
    const std::vector<Row> rows = query("SELECT max(version) FROM inertia_record_schema", {});
    const auto* v = std::get_if<long long>(&rows.front().front());
    return v != nullptr ? static_cast<int>(*v) : 0;
  }
  void refuse_newer(int version) const {
    if (version <= kSchemaVersion) return;
    throw InputError(fmt::format("{} has schema version {}, newer than this program's {}: refused, nothing written (use the "
                                 "newer inertia that wrote it)",
                                 describe(), version, kSchemaVersion));
  }

  std::string where_;
  std::unique_ptr<PGconn, Finish> connection_;
};

}  // namespace

std::unique_ptr<RecordDatabase> open_postgresql_record(const std::string& url) {
  return std::make_unique<PostgresqlRecordDatabase>(url);
}

}  // namespace inertia::record
