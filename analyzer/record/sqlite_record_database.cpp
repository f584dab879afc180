// The record in an embedded SQLite file: created on first use, its schema version in PRAGMA
// user_version, several writers through the write-ahead log (a writer waits up to 30 s for
// another's transaction), UPDATE and DELETE refused by triggers.
#include <fmt/format.h>
#include <sqlite3.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <thread>

#include "analyzer/record/record_database.hpp"
#include "common/input_error.hpp"

namespace inertia::record {

namespace {

/// Migration steps: kSqliteMigrations[k] takes a database from schema version k to k + 1. Each is
/// idempotent where it can be, so a writer that raced another to it does no harm.
constexpr const char* kSqliteMigrations[] = {
    R"sql(
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
)sql",
    R"sql(
ALTER TABLE characterization ADD COLUMN part TEXT NOT NULL DEFAULT '';
ALTER TABLE characterization ADD COLUMN unit TEXT NOT NULL DEFAULT '';
CREATE INDEX IF NOT EXISTS characterization_part ON characterization(sensor_kind, part);
)sql",
};
static_assert(std::size(kSqliteMigrations) == kSchemaVersion);

class SqliteRecordDatabase final : public RecordDatabase {
 public:
  explicit SqliteRecordDatabase(const std::filesystem::path& file) : file_(file) {
    if (!file.parent_path().empty()) std::filesystem::create_directories(file.parent_path());
    if (sqlite3_open_v2(file.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr) !=
        SQLITE_OK) {
      const std::string why = db_ != nullptr ? sqlite3_errmsg(db_) : "out of memory";
      close();
      throw InputError(fmt::format("{}: cannot open: {}", describe(), why));
    }
    sqlite3_busy_timeout(db_, 30000);
    // The first read tells a damaged file or another kind of file from a database: nothing has
    // been written to it yet.
    int version = 0;
    {
      sqlite3_stmt* s = nullptr;
      int rc = sqlite3_prepare_v2(db_, "PRAGMA user_version", -1, &s, nullptr);
      if (rc == SQLITE_OK) rc = sqlite3_step(s);
      if (rc == SQLITE_ROW) version = sqlite3_column_int(s, 0);
      const std::string why = sqlite3_errmsg(db_);
      sqlite3_finalize(s);
      if (rc != SQLITE_ROW) {
        close();
        throw InputError(fmt::format("{} is damaged or not an SQLite database ({}); nothing was written to it", describe(), why));
      }
    }
    refuse_newer(version);
    {
      char* error = nullptr;
      if (sqlite3_exec(db_, "PRAGMA quick_check", nullptr, nullptr, &error) != SQLITE_OK) {
        const std::string why = error != nullptr ? error : "";
        sqlite3_free(error);
        close();
        throw InputError(fmt::format("{} is damaged ({}); nothing was written to it", describe(), why));
      }
    }
    // Switching to the write-ahead log takes the file for a moment, and SQLite does not wait for
    // it through the busy handler: two first writers at once retry until the other has done.
    if (when_free([&] { return exec_status("PRAGMA journal_mode=WAL"); }) != SQLITE_OK) execute("PRAGMA journal_mode=WAL");
    execute("PRAGMA foreign_keys=ON");
    if (version < kSchemaVersion) {
      if (when_free([&] { return exec_status("BEGIN IMMEDIATE"); }) != SQLITE_OK) execute("BEGIN IMMEDIATE");
      try {
        version = std::get<long long>(query("PRAGMA user_version", {}).front().front());   // another writer may have migrated
        refuse_newer(static_cast<int>(version));
        for (int step = version; step < kSchemaVersion; ++step) execute(kSqliteMigrations[step]);
        execute(fmt::format("PRAGMA user_version = {}", kSchemaVersion).c_str());
        execute("COMMIT");
      } catch (...) {
        rollback();
        throw;
      }
    }
  }
  ~SqliteRecordDatabase() override { close(); }
  SqliteRecordDatabase(const SqliteRecordDatabase&) = delete;
  SqliteRecordDatabase& operator=(const SqliteRecordDatabase&) = delete;

  std::vector<Row> query(std::string_view sql, const std::vector<Value>& parameters) override {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db_, sql.data(), static_cast<int>(sql.size()), &s, nullptr) != SQLITE_OK) fail();
    const std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)> statement(s, &sqlite3_finalize);
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      const int index = static_cast<int>(i) + 1;
      const Value& v = parameters[i];
      if (const auto* text = std::get_if<std::string>(&v)) {
        sqlite3_bind_text(s, index, text->c_str(), static_cast<int>(text->size()), SQLITE_TRANSIENT);
      } else if (const auto* real = std::get_if<double>(&v); real != nullptr && std::isfinite(*real)) {
        sqlite3_bind_double(s, index, *real);
      } else if (const auto* integer = std::get_if<long long>(&v)) {
        sqlite3_bind_int64(s, index, *integer);
      } else {
        sqlite3_bind_null(s, index);
      }
    }
    std::vector<Row> rows;
    for (;;) {
      const int rc = sqlite3_step(s);
      if (rc == SQLITE_DONE) return rows;
      if (rc != SQLITE_ROW) fail();
      Row row(static_cast<std::size_t>(sqlite3_column_count(s)));
      for (int c = 0; c < sqlite3_column_count(s); ++c) {
        switch (sqlite3_column_type(s, c)) {
          case SQLITE_INTEGER: row[c] = static_cast<long long>(sqlite3_column_int64(s, c)); break;
          case SQLITE_FLOAT: row[c] = sqlite3_column_double(s, c); break;
          case SQLITE_NULL: break;
          default: row[c] = std::string(reinterpret_cast<const char*>(sqlite3_column_text(s, c)), sqlite3_column_bytes(s, c));
        }
      }
      rows.push_back(std::move(row));
    }
  }
  void begin_write() override { execute("BEGIN IMMEDIATE"); }
  void commit() override { execute("COMMIT"); }
  void rollback() noexcept override { sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr); }
  [[nodiscard]] std::string describe() const override { return "record database " + file_.string(); }

 private:
  void close() {
    sqlite3_close(db_);
    db_ = nullptr;
  }
  void refuse_newer(int version) {
    if (version <= kSchemaVersion) return;
    close();
    throw InputError(fmt::format("{} has schema version {}, newer than this program's {}: refused, nothing written (use the "
                                 "newer inertia that wrote it)",
                                 describe(), version, kSchemaVersion));
  }
  [[noreturn]] void fail() const { throw std::runtime_error(fmt::format("{}: {}", describe(), sqlite3_errmsg(db_))); }
  int exec_status(const char* sql) { return sqlite3_exec(db_, sql, nullptr, nullptr, nullptr); }
  void execute(const char* sql) {
    char* error = nullptr;
    if (sqlite3_exec(db_, sql, nullptr, nullptr, &error) != SQLITE_OK) {
      const std::string why = error != nullptr ? error : sqlite3_errmsg(db_);
      sqlite3_free(error);
      throw std::runtime_error(fmt::format("{}: {}", describe(), why));
    }
  }
  static int when_free(const std::function<int()>& step) {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    for (;;) {
      const int rc = step();
      if ((rc != SQLITE_BUSY && rc != SQLITE_LOCKED) || std::chrono::steady_clock::now() > give_up) return rc;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }

  std::filesystem::path file_;
  sqlite3* db_ = nullptr;
};

}  // namespace

std::unique_ptr<RecordDatabase> open_sqlite_record(const std::filesystem::path& file) {
  return std::make_unique<SqliteRecordDatabase>(file);
}

}  // namespace inertia::record
