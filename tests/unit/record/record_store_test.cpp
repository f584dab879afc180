// The lab's record on real SQLite files: round trip, append-only, a newer schema and a damaged
// file refused without a write, a writer killed mid-transaction (SIGKILL) leaving no partial
// row, and two writer processes at once.
#include "analyzer/record/record_store.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <thread>

#include "common/input_error.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia::record {
namespace {

namespace fs = std::filesystem;

Characterization sample(const std::string& serial, double bias, double u) {
  Characterization c;
  c.serial = serial;
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

TEST(RecordStore, RoundTripHistoryAndTheNormalizedError) {
  const inertia::testing::TempDir dir("inertia-record");
  const fs::path db = dir.path / "lab" / "record.sqlite";   // created on first use, folder too
  {
    RecordStore store(db);
    EXPECT_EQ(store.add(sample("SN1", 4000.0, 80.0)), 1);
    EXPECT_EQ(store.add(sample("SN2", 3000.0, 80.0)), 2);
    EXPECT_EQ(store.add(sample("SN1", 4300.0, 80.0)), 3);   // a re-run: a new row
  }
  const RecordStore store(db);
  EXPECT_EQ(store.list().size(), 3u);
  ASSERT_EQ(store.list("SN1").size(), 2u);
  const std::optional<Characterization> shown = store.show(3);
  ASSERT_TRUE(shown.has_value());
  EXPECT_EQ(shown->model_toml, "sensor = \"accelerometer\"\n");
  EXPECT_EQ(shown->input_sha256, std::string(64, 'a'));
  const std::vector<ParameterPoint> h = store.history("SN1", "bias");
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[1].value, 4300.0);
  EXPECT_GT(normalized_error(*h[1].value, *h[1].expanded_uncertainty, *h[0].value, *h[0].expanded_uncertainty), 1.0);   // 300 / 113
  const std::vector<ParameterPoint> undetermined = store.history("SN1", "second-order nonlinearity");
  ASSERT_EQ(undetermined.size(), 2u);
  EXPECT_FALSE(undetermined[0].value.has_value());   // never a number
  EXPECT_EQ(undetermined[0].status, "not determined");
}

TEST(RecordStore, IsAppendOnly) {
  const inertia::testing::TempDir dir("inertia-record");
  const fs::path db = dir.path / "record.sqlite";
  RecordStore(db).add(sample("SN1", 4000.0, 80.0));
  EXPECT_NE(sqlite_exec(db, "UPDATE characterization SET serial = 'X'"), SQLITE_OK);
  EXPECT_NE(sqlite_exec(db, "DELETE FROM parameter"), SQLITE_OK);
  EXPECT_EQ(RecordStore(db).list("SN1").size(), 1u);
}

TEST(RecordStore, ANewerSchemaOrADamagedFileIsRefusedAndNotWritten) {
  const inertia::testing::TempDir dir("inertia-record");
  const fs::path newer = dir.path / "newer.sqlite";
  RecordStore(newer).add(sample("SN1", 4000.0, 80.0));
  ASSERT_EQ(sqlite_exec(newer, "PRAGMA user_version = 7"), SQLITE_OK);
  const std::string before = bytes_of(newer);
  try {
    RecordStore store(newer);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 7, newer"), std::string::npos) << e.what();
  }
  EXPECT_EQ(bytes_of(newer), before);

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

/// A child that appends records as fast as it can until killed.
pid_t writer(const fs::path& db, const std::string& serial, int count) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    try {
      RecordStore store(db);
      for (int i = 0; count < 0 || i < count; ++i) store.add(sample(serial, 4000.0 + i, 80.0));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "writer %s: %s\n", serial.c_str(), e.what());
      ::_exit(1);
    }
    ::_exit(0);
  }
  return pid;
}

TEST(RecordStore, AWriterKilledMidTransactionLeavesNoPartialRecord) {
  const inertia::testing::TempDir dir("inertia-record");
  const fs::path db = dir.path / "record.sqlite";
  RecordStore(db).add(sample("SN0", 1.0, 1.0));   // the schema exists before the child starts
  for (int round = 0; round < 5; ++round) {
    const pid_t pid = writer(db, "SN1", -1);
    std::this_thread::sleep_for(std::chrono::milliseconds(40 + 17 * round));
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status));
  }
  sqlite3* h = nullptr;
  ASSERT_EQ(sqlite3_open(db.c_str(), &h), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(h, "PRAGMA integrity_check", -1, &s, nullptr);
  ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(s, 0)), "ok");
  sqlite3_finalize(s);
  // Every characterization has both its parameters: none was cut between its rows.
  sqlite3_prepare_v2(h,
                     "SELECT COUNT(*) FROM characterization c WHERE (SELECT COUNT(*) FROM parameter p WHERE "
                     "p.characterization_id = c.id) != 2",
                     -1, &s, nullptr);
  ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(s, 0), 0);
  sqlite3_finalize(s);
  sqlite3_close(h);
  const std::size_t rows = RecordStore(db).list("SN1").size();
  std::cout << "[ figures ] " << rows << " records written in 5 killed runs\n";
  EXPECT_GT(rows, 0u);
}

TEST(RecordStore, TwoWritersAtOnceBothLand) {
  const inertia::testing::TempDir dir("inertia-record");
  const fs::path db = dir.path / "record.sqlite";
  const pid_t a = writer(db, "A", 30), b = writer(db, "B", 30);
  int status_a = 0, status_b = 0;
  ::waitpid(a, &status_a, 0);
  ::waitpid(b, &status_b, 0);
  EXPECT_TRUE(WIFEXITED(status_a) && WEXITSTATUS(status_a) == 0);
  EXPECT_TRUE(WIFEXITED(status_b) && WEXITSTATUS(status_b) == 0);
  const RecordStore store(db);
  EXPECT_EQ(store.list("A").size(), 30u);
  EXPECT_EQ(store.list("B").size(), 30u);
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
