#pragma once
// The connection under the lab's record: the few operations RecordStore needs, so that its
// queries and their reading are written once for every database behind it. Two are provided: an
// embedded SQLite file (the default) and a PostgreSQL server that several bench PCs share.
//
// SQL is written once for both, with numbered parameters $1, $2, ...: PostgreSQL's own syntax,
// and to SQLite named parameters whose index is their order of first appearance, so each $n must
// first appear after $1 ... $n-1.
//
// Opening a database migrates it to kSchemaVersion, step by step, under the database's own lock
// (two first writers at once do not both migrate); a database of a newer schema is refused with
// nothing written.
#include <memory>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <filesystem>

namespace inertia::record {

/// The record's schema version. 1: characterization and parameter; 2: characterization.part and .unit.
inline constexpr int kSchemaVersion = 2;

using Value = std::variant<std::monostate, long long, double, std::string>;   // monostate: NULL
using Row = std::vector<Value>;

class RecordDatabase {
 public:
  virtual ~RecordDatabase() = default;
  /// Runs one statement with its parameters; returns its rows (empty for one that returns none).
  virtual std::vector<Row> query(std::string_view sql, const std::vector<Value>& parameters) = 0;
  /// A transaction that writes: it holds the database's write lock from its start, so that two
  /// writers serialize instead of failing at commit.
  virtual void begin_write() = 0;
  virtual void commit() = 0;
  virtual void rollback() noexcept = 0;
  /// "record database <where>", for messages (a PostgreSQL URL without its password).
  [[nodiscard]] virtual std::string describe() const = 0;
};

/// Whether `location` names a PostgreSQL server (postgresql:// or postgres://) instead of a file.
bool is_postgresql_url(std::string_view location);

/// Opens (creating on first use, file and folder) the SQLite record at `file`. Throws InputError,
/// writing nothing, for a damaged file, a file that is not a database, and a newer schema.
std::unique_ptr<RecordDatabase> open_sqlite_record(const std::filesystem::path& file);
/// Connects to the PostgreSQL record at `url` (libpq's connection URI), creating its tables on
/// first use. Throws InputError for a server it cannot reach and for a newer schema.
std::unique_ptr<RecordDatabase> open_postgresql_record(const std::string& url);

}  // namespace inertia::record
