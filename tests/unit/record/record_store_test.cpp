// The lab's record on both its databases, for real: SQLite files, and a throwaway PostgreSQL
// server of the test's own (tests/support/throwaway_postgresql.sh; where this machine cannot run
// one, the PostgreSQL cases skip with the reason, and fail under CI=true). On each: round trip,
// append-only, a newer schema refused without a write, a writer killed mid-transaction (SIGKILL)
// leaving no partial row, two writer processes at once, the population for compare. SQLite's
// own: a damaged file refused without a write, a schema-1 file migrated.
#include "analyzer/record/record_store.hpp"

#include <fmt/format.h>

#include <gtest/gtest.h>
#include <libpq-fe.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <thread>

#include "analyzer/commands/record.hpp"
#include "common/input_error.hpp"
#include "tests/support/scratch_dirs.hpp"
#include "tests/support/skip_or_fail.hpp"

namespace inertia::record {
namespace {

namespace fs = std::filesystem;

Characterization sample(const std::string& serial, double bias, double u, const std::string& part = "QA-2000") {
  Characterization c;
  c.serial = serial;
  c.part = part;
  c.unit = "imu7";
  c.sensor_name = "acc1";
  c.sensor_kind = "accelerometer";
  c.bench = "sim-rotation-table";
  c.operator_name = "tester";
  c.plan = "multipoint, rate-series";
  c.software = "inertia test";
  c.input_path = "/data/acc1";
  c.input_sha256 = std::string(64, 'a');
  c.model_toml = "sensor = \"accelerometer\"\n";
  c.sheet_json = "{}";
  c.report_path = "/data/out/report.md";
  report::SheetEntry bias_entry;
  bias_entry.name = "bias";
  bias_entry.unit = "ug";
  bias_entry.value = bias;
  bias_entry.expanded_uncertainty = u;
  report::SheetEntry undetermined;
  undetermined.name = "second-order nonlinearity";
  undetermined.unit = "ug/g^2";
  undetermined.status = report::SheetEntry::Status::Undetermined;
  undetermined.reason = "not excited";
  c.parameters = {bias_entry, undetermined};
  return c;
}

std::string bytes_of(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

int sqlite_exec(const fs::path& db, const char* sql) {
  sqlite3* h = nullptr;
  sqlite3_open(db.c_str(), &h);
  const int rc = sqlite3_exec(h, sql, nullptr, nullptr, nullptr);
  sqlite3_close(h);
  return rc;
}


/// The throwaway PostgreSQL server, started on first use and stopped when the test binary exits.
class PostgresqlServer {
 public:
  PostgresqlServer() : dir_("inertia-pg") {
    const std::string script = std::string(INERTIA_SOURCE_DIR) + "/tests/support/throwaway_postgresql.sh";
    const std::string command = script + " start " + dir_.path.string() + " 2>" + (dir_.path / "why").string();
    FILE* p = ::popen(command.c_str(), "r");
    char line[512] = {};
    if (p != nullptr && std::fgets(line, sizeof line, p) != nullptr) url_ = line;
    const int status = p != nullptr ? ::pclose(p) : -1;
    while (!url_.empty() && (url_.back() == '\n' || url_.back() == ' ')) url_.pop_back();
    if (status != 0) {
      std::ifstream why(dir_.path / "why");
      why_not_ = std::string(std::istreambuf_iterator<char>(why), {});
      if (why_not_.empty()) why_not_ = "the throwaway server did not start (status " + std::to_string(status) + ")";
      url_.clear();
    }
  }
  ~PostgresqlServer() {
    if (!url_.empty())
      std::system((std::string(INERTIA_SOURCE_DIR) + "/tests/support/throwaway_postgresql.sh stop " + dir_.path.string()).c_str());
  }
  PostgresqlServer(const PostgresqlServer&) = delete;
  PostgresqlServer& operator=(const PostgresqlServer&) = delete;
  [[nodiscard]] bool running() const { return !url_.empty(); }
  [[nodiscard]] const std::string& why_not() const { return why_not_; }
  /// The URL of database `name` on the server (the server's start URL names "postgres").
  [[nodiscard]] std::string url_of(const std::string& name) const {
    std::string u = url_;
    u.replace(u.find("/postgres?"), 10, "/" + name + "?");
    return u;
  }

 private:
  inertia::testing::TempDir dir_;
  std::string url_, why_not_;
};

PostgresqlServer& postgresql_server() {
  static PostgresqlServer server;
  return server;
}

/// Runs `sql` on the PostgreSQL database at `url` outside RecordStore; its first value, or
/// nullopt when the statement failed.
std::optional<std::string> postgresql_exec(const std::string& url, const std::string& sql) {
  PGconn* c = PQconnectdb(url.c_str());
  std::optional<std::string> out;
  if (PQstatus(c) == CONNECTION_OK) {
    PGresult* r = PQexec(c, sql.c_str());
    const ExecStatusType status = PQresultStatus(r);
    if (status == PGRES_TUPLES_OK) out = PQntuples(r) > 0 ? std::string(PQgetvalue(r, 0, 0)) : std::string();
    if (status == PGRES_COMMAND_OK) out = std::string();
    PQclear(r);
  }
  PQfinish(c);
  return out;
}

std::optional<std::string> sqlite_value(const fs::path& db, const std::string& sql) {
  sqlite3* h = nullptr;
  sqlite3_open(db.c_str(), &h);
  sqlite3_stmt* s = nullptr;
  std::optional<std::string> out;
  if (sqlite3_prepare_v2(h, sql.c_str(), -1, &s, nullptr) == SQLITE_OK) {
    const int rc = sqlite3_step(s);
    if (rc == SQLITE_ROW) out = sqlite3_column_text(s, 0) != nullptr ? reinterpret_cast<const char*>(sqlite3_column_text(s, 0)) : "";
    if (rc == SQLITE_DONE) out = std::string();
  }
  sqlite3_finalize(s);
  sqlite3_close(h);
  return out;
}

/// One test's fresh record on the backend under test, and raw SQL on it beside RecordStore.
class RecordBackend : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (postgresql()) {
      if (!postgresql_server().running()) INERTIA_SKIP_OR_FAIL_IN_CI("no PostgreSQL server for the test: " + postgresql_server().why_not());
      static int databases = 0;
      const std::string name = "record_" + std::to_string(::getpid()) + "_" + std::to_string(++databases);
      ASSERT_TRUE(postgresql_exec(postgresql_server().url_of("postgres"), "CREATE DATABASE " + name).has_value());
      location_ = postgresql_server().url_of(name);
    } else {
      location_ = (dir_.path / "record.sqlite").string();
    }
  }
  [[nodiscard]] bool postgresql() const { return GetParam() == "postgresql"; }
  [[nodiscard]] const std::string& location() const { return location_; }
  /// `sql`'s first value outside RecordStore; nullopt when the database refused the statement.
  [[nodiscard]] std::optional<std::string> raw(const std::string& sql) const {
    return postgresql() ? postgresql_exec(location_, sql) : sqlite_value(location_, sql);
  }
  [[nodiscard]] long long count(const std::string& sql) const { return std::stoll(raw(sql).value_or("-1")); }

 private:
  inertia::testing::TempDir dir_{"inertia-record"};
  std::string location_;
};

TEST_P(RecordBackend, RoundTripHistoryAndTheNormalizedError) {
  {
    RecordStore store(location());
    EXPECT_EQ(store.add(sample("SN1", 4000.0, 80.0)), 1);
    EXPECT_EQ(store.add(sample("SN2", 3000.0, 80.0)), 2);
    EXPECT_EQ(store.add(sample("SN1", 4300.0 + 0.1 + 0.2, 1.0 / 3.0)), 3);   // a re-run: a new row
  }
  const RecordStore store(location());
  EXPECT_EQ(store.list().size(), 3u);
  ASSERT_EQ(store.list("SN1").size(), 2u);
  EXPECT_EQ(store.list("SN1")[1].part, "QA-2000");
  EXPECT_EQ(store.list("SN1")[1].unit, "imu7");
  const std::optional<Characterization> shown = store.show(3);
  ASSERT_TRUE(shown.has_value());
  EXPECT_EQ(shown->model_toml, "sensor = \"accelerometer\"\n");
  EXPECT_EQ(shown->input_sha256, std::string(64, 'a'));
  EXPECT_FALSE(store.show(99).has_value());
  const std::vector<ParameterPoint> h = store.history("SN1", "bias");
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[1].value, 4300.0 + 0.1 + 0.2);   // every bit of a double, both ways
  EXPECT_EQ(h[1].expanded_uncertainty, 1.0 / 3.0);
  EXPECT_EQ(h[1].unit, "ug");
  EXPECT_GT(normalized_error(*h[1].value, *h[1].expanded_uncertainty, *h[0].value, *h[0].expanded_uncertainty), 1.0);   // 300 / 80
  const std::vector<ParameterPoint> undetermined = store.history("SN1", "second-order nonlinearity");
  ASSERT_EQ(undetermined.size(), 2u);
  EXPECT_FALSE(undetermined[0].value.has_value());   // never a number
  EXPECT_EQ(undetermined[0].status, "not determined");
}

TEST_P(RecordBackend, ThePopulationIsEachSerialsLatestOfTheKindAndPart) {
  RecordStore store(location());
  store.add(sample("SN1", 4000.0, 80.0));
  store.add(sample("SN2", 3000.0, 80.0));
  store.add(sample("SN1", 4100.0, 80.0));                 // SN1's latest
  store.add(sample("SN3", 5000.0, 80.0, "JA-5"));         // another part
  Characterization gyro = sample("SN4", 1.0, 1.0);
  gyro.sensor_kind = "gyroscope";
  store.add(gyro);
  const std::vector<PopulationValue> population = store.population("accelerometer", "QA-2000");
  ASSERT_EQ(population.size(), 2u);   // the determined bias of SN2 and of SN1's latest
  EXPECT_EQ(population[0].serial, "SN2");
  EXPECT_EQ(population[0].value, 3000.0);
  EXPECT_EQ(population[1].serial, "SN1");
  EXPECT_EQ(population[1].id, 3);
  EXPECT_EQ(population[1].value, 4100.0);
  EXPECT_EQ(store.population("accelerometer", "JA-5").size(), 1u);
  EXPECT_TRUE(store.population("accelerometer", "").empty());
}

TEST_P(RecordBackend, IsAppendOnly) {
  RecordStore(location()).add(sample("SN1", 4000.0, 80.0));
  EXPECT_FALSE(raw("UPDATE characterization SET serial = 'X'").has_value());
  EXPECT_FALSE(raw("DELETE FROM parameter").has_value());
  EXPECT_FALSE(raw("DELETE FROM characterization").has_value());
  if (postgresql()) {
    EXPECT_FALSE(raw("TRUNCATE parameter").has_value());
  }
  EXPECT_EQ(RecordStore(location()).list("SN1").size(), 1u);
  EXPECT_EQ(count("SELECT COUNT(*) FROM parameter"), 2);
}

TEST_P(RecordBackend, ANewerSchemaIsRefusedAndNothingWritten) {
  RecordStore(location()).add(sample("SN1", 4000.0, 80.0));
  ASSERT_TRUE(raw(postgresql() ? "UPDATE inertia_record_schema SET version = 7" : "PRAGMA user_version = 7").has_value());
  const std::string before = postgresql() ? std::string() : bytes_of(location());
  try {
    RecordStore store(location());
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 7, newer"), std::string::npos) << e.what();
  }
  if (!postgresql()) {
    EXPECT_EQ(bytes_of(location()), before);
  }
  EXPECT_EQ(count("SELECT COUNT(*) FROM characterization"), 1);
  EXPECT_EQ(raw(postgresql() ? "SELECT version FROM inertia_record_schema" : "PRAGMA user_version"), "7");
}

/// A child that appends records as fast as it can until killed.
pid_t writer(const std::string& location, const std::string& serial, int count) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    try {
      RecordStore store(location);
      for (int i = 0; count < 0 || i < count; ++i) store.add(sample(serial, 4000.0 + i, 80.0));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "writer %s: %s\n", serial.c_str(), e.what());
      ::_exit(1);
    }
    ::_exit(0);
  }
  return pid;
}

TEST_P(RecordBackend, AWriterKilledMidTransactionLeavesNoPartialRecord) {
  RecordStore(location()).add(sample("SN0", 1.0, 1.0));   // the schema exists before the child starts
  for (int round = 0; round < 5; ++round) {
    const pid_t pid = writer(location(), "SN1", -1);
    std::this_thread::sleep_for(std::chrono::milliseconds(60 + 17 * round));
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status));
  }
  if (!postgresql()) {
    EXPECT_EQ(raw("PRAGMA integrity_check"), "ok");
  }
  // Every characterization has both its parameters: none was cut between its rows.
  EXPECT_EQ(count("SELECT COUNT(*) FROM characterization c WHERE (SELECT COUNT(*) FROM parameter p WHERE "
                  "p.characterization_id = c.id) != 2"),
            0);
  const std::size_t rows = RecordStore(location()).list("SN1").size();
  std::cout << "[ figures ] " << GetParam() << ": " << rows << " records written in 5 killed runs\n";
  EXPECT_GT(rows, 0u);
}

TEST_P(RecordBackend, TwoWritersAtOnceBothLand) {
  // Both start on a new record: they race to create its schema too.
  const pid_t a = writer(location(), "A", 30), b = writer(location(), "B", 30);
  int status_a = 0, status_b = 0;
  ::waitpid(a, &status_a, 0);
  ::waitpid(b, &status_b, 0);
  EXPECT_TRUE(WIFEXITED(status_a) && WEXITSTATUS(status_a) == 0);
  EXPECT_TRUE(WIFEXITED(status_b) && WEXITSTATUS(status_b) == 0);
  const RecordStore store(location());
  EXPECT_EQ(store.list("A").size(), 30u);
  EXPECT_EQ(store.list("B").size(), 30u);
}

INSTANTIATE_TEST_SUITE_P(Databases, RecordBackend, ::testing::Values("sqlite", "postgresql"),
                         [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

TEST(RecordStore, ADamagedFileIsRefusedAndNotWritten) {
  const inertia::testing::TempDir dir("inertia-record");
  const fs::path damaged = dir.path / "damaged.sqlite";
  std::ofstream(damaged) << std::string(4096, 'x');
  const std::string junk = bytes_of(damaged);
  try {
    RecordStore store(damaged);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("damaged or not an SQLite database"), std::string::npos) << e.what();
  }
  EXPECT_EQ(bytes_of(damaged), junk);
}

TEST(RecordStore, ASchemaOneFileIsMigratedWithItsRecordsKept) {
  const inertia::testing::TempDir dir("inertia-record");
  const fs::path db = dir.path / "v1.sqlite";
  // A record as schema 1 wrote it (no part), with one characterization.
  ASSERT_EQ(sqlite_exec(db, "CREATE TABLE characterization (id INTEGER PRIMARY KEY AUTOINCREMENT, recorded_utc TEXT NOT NULL, "
                            "serial TEXT NOT NULL, sensor_name TEXT NOT NULL, sensor_kind TEXT NOT NULL, bench TEXT NOT NULL, "
                            "operator TEXT NOT NULL, plan TEXT NOT NULL, software TEXT NOT NULL, input_path TEXT NOT NULL, "
                            "input_sha256 TEXT NOT NULL, model_toml TEXT NOT NULL, sheet_json TEXT NOT NULL, report_path TEXT NOT NULL);"
                            "CREATE TABLE parameter (characterization_id INTEGER NOT NULL REFERENCES characterization(id), "
                            "name TEXT NOT NULL, unit TEXT NOT NULL, status TEXT NOT NULL, value REAL, expanded_uncertainty REAL, "
                            "PRIMARY KEY (characterization_id, name));"
                            "CREATE TRIGGER characterization_append_only_delete BEFORE DELETE ON characterization "
                            "BEGIN SELECT RAISE(ABORT, 'the record is append-only'); END;"
                            "INSERT INTO characterization VALUES (1, '2026-01-01T00:00:00Z', 'OLD', 'acc1', 'accelerometer', 'b', 'o', "
                            "'p', 's', 'i', 'h', 'm', '{}', 'r');"
                            "INSERT INTO parameter VALUES (1, 'bias', 'ug', 'determined', 12.5, 1.5);"
                            "PRAGMA user_version = 1;"),
            SQLITE_OK);
  RecordStore store(db);
  EXPECT_EQ(sqlite_value(db, "PRAGMA user_version"), std::to_string(kSchemaVersion));
  ASSERT_EQ(store.list("OLD").size(), 1u);
  EXPECT_EQ(store.list("OLD")[0].part, "");
  EXPECT_EQ(store.list("OLD")[0].unit, "");
  EXPECT_EQ(store.history("OLD", "bias").at(0).value, 12.5);
  EXPECT_EQ(store.add(sample("NEW", 1.0, 1.0)), 2);
  EXPECT_EQ(store.list("NEW")[0].part, "QA-2000");
  EXPECT_NE(sqlite_exec(db, "DELETE FROM characterization"), SQLITE_OK);   // still append-only after the migration
}

TEST(RecordStore, PercentileRankCountsTiesAsHalf) {
  EXPECT_TRUE(std::isnan(percentile_rank(1.0, {})));
  EXPECT_EQ(percentile_rank(5.0, {1.0, 2.0, 3.0, 4.0}), 100.0);
  EXPECT_EQ(percentile_rank(0.0, {1.0, 2.0, 3.0, 4.0}), 0.0);
  EXPECT_EQ(percentile_rank(2.5, {1.0, 2.0, 3.0, 4.0}), 50.0);
  EXPECT_EQ(percentile_rank(2.0, {1.0, 2.0, 3.0, 4.0}), 37.5);   // one below, one tie
}

TEST(RecordStore, CompareGivesEachParametersPercentileAmongTheOtherSerials) {
  const inertia::testing::TempDir dir("inertia-record");
  const std::string db = (dir.path / "record.sqlite").string();
  {
    RecordStore store(db);
    for (int k = 1; k <= 12; ++k) store.add(sample(fmt::format("SN{}", k), 100.0 * k, 80.0));
    store.add(sample("SN5", 1050.0, 80.0));   // SN5's latest: above 9 of the 11 others (100 ... 1000 without 500)
    store.add(sample("SN99", 1.0, 80.0, "another part"));
  }
  std::ostringstream out;
  EXPECT_EQ(commands::run_record_compare(db, "SN5", out), 0);
  const std::string text = out.str();
  EXPECT_NE(text.find("part QA-2000"), std::string::npos) << text;
  EXPECT_NE(text.find(": 11 serial(s)"), std::string::npos) << text;
  const std::size_t bias = text.find("\nbias ");
  ASSERT_NE(bias, std::string::npos) << text;
  const std::string line = text.substr(bias + 1, text.find('\n', bias + 1) - bias - 1);
  EXPECT_NE(line.find("1050"), std::string::npos) << line;
  EXPECT_NE(line.find("  11 "), std::string::npos) << line;          // n
  EXPECT_NE(line.find("[100, 1200]"), std::string::npos) << line;    // SN5's earlier 500 is not in it
  EXPECT_NE(line.find("  700  "), std::string::npos) << line;        // the others' median
  EXPECT_NE(line.find(" 82%"), std::string::npos) << line;           // 9 of 11 below
  std::ostringstream alone;
  EXPECT_EQ(commands::run_record_compare(db, "SN99", alone), 0);
  EXPECT_NE(alone.str().find("nothing to compare with"), std::string::npos) << alone.str();
  std::ostringstream unknown;
  EXPECT_THROW(commands::run_record_compare(db, "SN-NONE", unknown), InputError);
}

TEST(RecordStore, HistoryPlotsTheValuesWithTheirUncertaintyAndTheDrift) {
  if (std::system("gnuplot --version >/dev/null 2>&1") != 0) INERTIA_SKIP_OR_FAIL_IN_CI("gnuplot is not installed");
  const inertia::testing::TempDir dir("inertia-record");
  const std::string db = (dir.path / "record.sqlite").string();
  {
    RecordStore store(db);
    for (const double bias : {4000.0, 4010.0, 4600.0}) store.add(sample("SN1", bias, 80.0));
  }
  std::ostringstream out;
  const fs::path plot = dir.path / "bias.svg";
  ASSERT_EQ(commands::run_record_history(db, "SN1", "bias", out, plot), 0) << out.str();
  EXPECT_NE(out.str().find("drift: characterization 3"), std::string::npos) << out.str();
  const std::string svg = bytes_of(plot);
  EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("drift (family-wise 5 %)"), std::string::npos);
  EXPECT_NE(svg.find("#3"), std::string::npos);   // the third characterization's tic
}

TEST(RecordStore, InputHashCoversTheDatasetsFiles) {
  const inertia::testing::TempDir dir("inertia-record");
  fs::create_directories(dir.path / "ds");
  std::ofstream(dir.path / "ds" / "dataset.toml") << "sensor = \"accelerometer\"\n";
  std::ofstream(dir.path / "ds" / "a.csv") << "t,y\n0,1\n";
  const std::string first = input_sha256(dir.path / "ds");
  EXPECT_EQ(first.size(), 64u);
  std::ofstream(dir.path / "ds" / "a.csv") << "t,y\n0,2\n";
  EXPECT_NE(input_sha256(dir.path / "ds"), first);
  std::ofstream(dir.path / "x") << "abc";
  EXPECT_EQ(input_sha256(dir.path / "x"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");   // SHA-256("abc")
}

}  // namespace
}  // namespace inertia::record
