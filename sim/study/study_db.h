// A study's results database, DIR/results.db (SQLite): table `results`, one
// row per point with its parameters, status, error and the report's scalar
// fields as columns (their report paths); table `points`, the points the
// study declares; table `study`, its name, file, point count and the ropsim
// that made it. docs/studies.md "Results" describes the columns.
#pragma once
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "sim/study/study.h"
#include "sim/study/study_tasks.h"

struct sqlite3;
struct sqlite3_stmt;

namespace ropsim {

/// A point's row as a study's database records it.
struct RowState {
  std::string status, error;                    ///< "ok" / "failed", the error
  StudyFailure failure = StudyFailure::kInput;  ///< when failed
};

/// A declared point as the database records it (table `points`).
struct RecordedPoint {
  std::string hash, params;  ///< params: params_json().dump() ("" in a folder that did not record them)
};

/// A row of table `results`: column name and typed value.
using StudyRow = std::vector<std::pair<std::string, nlohmann::ordered_json>>;

class StudyDb {
 public:
  enum class Mode { kWrite, kRead };
  /// kWrite: creates the tables (WAL journal while it writes; settle() ends
  /// it). kRead: read-only (SQLITE_OPEN_READONLY); a WAL database in a folder
  /// this process cannot write (read-only media: no -shm can be made) is
  /// opened immutable when no write-ahead log is left beside it. Throws
  /// UserError naming the file.
  explicit StudyDb(const std::string& path, Mode mode = Mode::kWrite);
  ~StudyDb();
  StudyDb(const StudyDb&) = delete;
  StudyDb& operator=(const StudyDb&) = delete;

  /// A writer that is done: the database back to a rollback journal, its
  /// write-ahead log folded in and removed, so that readers need no -shm file
  /// (a finished study reads from read-only media). Busy (a reader holds it):
  /// it stays in WAL until the next writer is done.
  void settle();

  bool has_table(const std::string& name);
  /// A value of table `study` ("" when absent).
  std::string meta(const std::string& key);
  void set_meta(const std::string& k, const std::string& v);
  /// The points the folder's study declares (table `points`); `declared` is
  /// false for a database that did not record them: then the points it holds
  /// results of.
  std::vector<RecordedPoint> recorded_points(bool& declared);
  /// Records the study's identity: its name, file and points (table
  /// `points`), and the place of each point's row in its expansion.
  void record_points(const Study& s, const std::vector<StudyPoint>& points);
  /// The row of every point in the table, by hash. A failure of a database
  /// without the `failure` column is an input failure.
  std::map<std::string, RowState> statuses();
  /// One row: every column a typed value; new columns are added as needed.
  void put_row(const StudyRow& row);

  void exec(const std::string& sql);
  sqlite3_stmt* prepare(const std::string& sql);

 private:
  void open_read();
  void step_done(sqlite3_stmt* st);
  [[noreturn]] void fail(const std::string& why);
  std::string path_;
  sqlite3* db_ = nullptr;
  std::set<std::string> columns_;
};

/// A point's row: its result (status "ok" and its report) or its failure
/// (status "failed", the error and the kind of failure).
StudyRow row_of(const StudyPoint& p, const std::string& status, const std::string& error,
                const nlohmann::ordered_json* report, StudyFailure failure = StudyFailure::kInput);

/// What a point's folder holds.
enum class FolderOutcome { kNone, kOk, kInputFailure, kHostFailure };
/// Records a finished point from its folder: its report, or its error (an
/// input error, error.txt, or its host's failure, host-error.txt).
FolderOutcome record_from_folder(StudyDb& db, const std::string& dir, const StudyPoint& p);

/// The study file a study folder was made from (its database records it).
std::string study_file_of(const std::string& dir);

/// What an export wrote.
struct StudyExport {
  std::string study;  ///< the study's name, as its database records it
  size_t rows = 0, ok = 0, failed = 0, columns = 0;
};

/// Writes the results table of a study folder as CSV: one row per point, one
/// column per parameter and metric (the report JSON left out). Opens the
/// database read-only, so a finished study on read-only media exports.
/// Throws UserError.
StudyExport export_study_csv(const std::string& dir, const std::string& csv_path);

}  // namespace ropsim
