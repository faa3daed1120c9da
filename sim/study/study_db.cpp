#include "sim/study/study_db.h"

#include <fmt/format.h>
#include <sqlite3.h>
#include <unistd.h>

#include <cctype>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "sim/study/study_folder.h"
#include "util/errors.h"
#include "util/output_file.h"
#include "util/version.h"

namespace fs = std::filesystem;

namespace ropsim {

namespace {

/// "file:" URI of a path (RFC 3986 escapes for what SQLite's URI parser reads).
std::string sqlite_uri(const fs::path& p) {
  std::string u = "file:";
  for (unsigned char c : fs::absolute(p).lexically_normal().string())
    u += std::isalnum(c) || std::strchr("/-._~", c) ? std::string(1, char(c)) : fmt::format("%{:02X}", c);
  return u;
}

/// A column of the current row as text ("" for null).
std::string text(sqlite3_stmt* st, int col) {
  const unsigned char* t = sqlite3_column_text(st, col);
  return t ? reinterpret_cast<const char*>(t) : "";
}

/// A column name as an SQL identifier.
std::string quote(const std::string& n) {
  std::string q = "\"";
  for (char c : n) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

/// The report's scalar fields as columns, by their report path (arrays and
/// the long texts stay in the report JSON).
void flatten(const nlohmann::ordered_json& j, const std::string& at,
             std::vector<std::pair<std::string, nlohmann::ordered_json>>& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it)
      flatten(it.value(), at.empty() ? it.key() : at + "." + it.key(), out);
  } else if (!j.is_array() && at != "command" && at != "hardware.resolved_toml") {
    out.emplace_back(at, j);
  }
}

}  // namespace

StudyDb::StudyDb(const std::string& path, Mode mode) : path_(path) {
  if (mode == Mode::kRead) {
    open_read();
    if (!has_table("results")) fail("not a study's database (no table 'results')");
  } else {
    if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) fail(sqlite3_errmsg(db_));
    exec("PRAGMA journal_mode=WAL");
    exec("PRAGMA synchronous=NORMAL");
    exec(
        "CREATE TABLE IF NOT EXISTS results (point TEXT PRIMARY KEY, point_index INTEGER, status TEXT, error TEXT, "
        "failure TEXT, report TEXT)");
    exec("CREATE TABLE IF NOT EXISTS study (key TEXT PRIMARY KEY, value TEXT)");
    exec("CREATE TABLE IF NOT EXISTS points (point TEXT PRIMARY KEY, point_index INTEGER, params TEXT)");
  }
  sqlite3_stmt* st = prepare("SELECT name FROM pragma_table_info('results')");
  while (sqlite3_step(st) == SQLITE_ROW) columns_.insert(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)));
  sqlite3_finalize(st);
  if (mode == Mode::kWrite && !columns_.count("failure")) {  // a database that predates the column
    exec("ALTER TABLE results ADD COLUMN failure TEXT");
    columns_.insert("failure");
  }
}

StudyDb::~StudyDb() { sqlite3_close(db_); }

void StudyDb::settle() { sqlite3_exec(db_, "PRAGMA journal_mode=DELETE", nullptr, nullptr, nullptr); }

bool StudyDb::has_table(const std::string& name) {
  sqlite3_stmt* st = prepare("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?");
  sqlite3_bind_text(st, 1, name.c_str(), -1, SQLITE_TRANSIENT);
  const bool has = sqlite3_step(st) == SQLITE_ROW;
  sqlite3_finalize(st);
  return has;
}

std::string StudyDb::meta(const std::string& key) {
  if (!has_table("study")) return "";
  sqlite3_stmt* st = prepare("SELECT value FROM study WHERE key = ?");
  sqlite3_bind_text(st, 1, key.c_str(), -1, SQLITE_TRANSIENT);
  std::string v;
  if (sqlite3_step(st) == SQLITE_ROW && sqlite3_column_text(st, 0))
    v = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
  sqlite3_finalize(st);
  return v;
}

std::vector<RecordedPoint> StudyDb::recorded_points(bool& declared) {
  std::vector<RecordedPoint> v;
  declared = has_table("points");
  if (declared) {
    sqlite3_stmt* st = prepare("SELECT point, params FROM points ORDER BY point_index");
    while (sqlite3_step(st) == SQLITE_ROW) v.push_back({text(st, 0), text(st, 1)});
    sqlite3_finalize(st);
    declared = !v.empty();
  }
  if (!declared) {
    sqlite3_stmt* st = prepare("SELECT point FROM results ORDER BY point_index");
    while (sqlite3_step(st) == SQLITE_ROW) v.push_back({text(st, 0), ""});
    sqlite3_finalize(st);
  }
  return v;
}

void StudyDb::record_points(const Study& s, const std::vector<StudyPoint>& points) {
  exec("BEGIN IMMEDIATE");
  exec("DELETE FROM points");
  for (const auto& p : points) {
    sqlite3_stmt* st = prepare("INSERT INTO points (point, point_index, params) VALUES (?, ?, ?)");
    const std::string params = p.params_json().dump();
    sqlite3_bind_text(st, 1, p.hash.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_int64(st, 2, int64_t(p.index));
    sqlite3_bind_text(st, 3, params.c_str(), -1, SQLITE_TRANSIENT);
    step_done(st);
    st = prepare("UPDATE results SET point_index = ? WHERE point = ?");
    sqlite3_bind_int64(st, 1, int64_t(p.index));
    sqlite3_bind_text(st, 2, p.hash.c_str(), -1, SQLITE_TRANSIENT);
    step_done(st);
  }
  set_meta("name", s.name);
  set_meta("file", s.path);
  set_meta("points", std::to_string(points.size()));
  set_meta("ropsim", std::string(ropsim_version()) + " " + ropsim_commit());
  exec("COMMIT");
}

void StudyDb::exec(const std::string& sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string e = err ? err : "?";
    sqlite3_free(err);
    fail(e);
  }
}

sqlite3_stmt* StudyDb::prepare(const std::string& sql) {
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) fail(sqlite3_errmsg(db_));
  return st;
}

std::map<std::string, RowState> StudyDb::statuses() {
  std::map<std::string, RowState> m;
  sqlite3_stmt* st = prepare("SELECT point, status, error, failure FROM results");
  while (sqlite3_step(st) == SQLITE_ROW)
    m[text(st, 0)] =
        RowState{text(st, 1), text(st, 2), text(st, 3) == "host" ? StudyFailure::kHost : StudyFailure::kInput};
  sqlite3_finalize(st);
  return m;
}

void StudyDb::set_meta(const std::string& k, const std::string& v) {
  sqlite3_stmt* st = prepare("INSERT OR REPLACE INTO study (key, value) VALUES (?, ?)");
  sqlite3_bind_text(st, 1, k.c_str(), -1, SQLITE_TRANSIENT);
  sqlite3_bind_text(st, 2, v.c_str(), -1, SQLITE_TRANSIENT);
  step_done(st);
}

void StudyDb::put_row(const StudyRow& row) {
  exec("BEGIN IMMEDIATE");
  for (const auto& [name, v] : row)
    if (!columns_.count(name)) {
      // A column first seen null (e.g. silicon.total.nand2_eq of a method without reference RTL) has no
      // type, so that the numbers of later points stay numbers (a TEXT column would store them as text).
      const char* type = v.is_null()                               ? ""
                         : v.is_number_integer() || v.is_boolean() ? "INTEGER"
                         : v.is_number()                           ? "REAL"
                                                                   : "TEXT";
      exec(fmt::format("ALTER TABLE results ADD COLUMN {} {}", quote(name), type));
      columns_.insert(name);
    }
  std::string cols, marks;
  for (const auto& [name, v] : row) {
    cols += (cols.empty() ? "" : ", ") + quote(name);
    marks += marks.empty() ? "?" : ", ?";
  }
  sqlite3_stmt* st = prepare("INSERT OR REPLACE INTO results (" + cols + ") VALUES (" + marks + ")");
  int i = 1;
  for (const auto& [name, v] : row) {
    if (v.is_null())
      sqlite3_bind_null(st, i);
    else if (v.is_boolean())
      sqlite3_bind_int64(st, i, v.get<bool>() ? 1 : 0);
    else if (v.is_number_unsigned())
      sqlite3_bind_int64(st, i, int64_t(v.get<uint64_t>()));
    else if (v.is_number_integer())
      sqlite3_bind_int64(st, i, v.get<int64_t>());
    else if (v.is_number())
      sqlite3_bind_double(st, i, v.get<double>());
    else {
      const std::string s = v.is_string() ? v.get<std::string>() : v.dump();
      sqlite3_bind_text(st, i, s.c_str(), -1, SQLITE_TRANSIENT);
    }
    ++i;
  }
  step_done(st);
  exec("COMMIT");
}

void StudyDb::open_read() {
  const auto probe = [&] { return sqlite3_exec(db_, "SELECT count(*) FROM sqlite_master", nullptr, nullptr, nullptr); };
  int rc = sqlite3_open_v2(path_.c_str(), &db_, SQLITE_OPEN_READONLY, nullptr);
  if (rc == SQLITE_OK) rc = probe();
  if (rc == SQLITE_OK) return;
  const std::string why = sqlite3_errmsg(db_);
  std::error_code ec;
  const fs::path wal = path_ + "-wal";
  const bool log_left = fs::exists(wal, ec) && fs::file_size(wal, ec) > 0;
  if (rc == SQLITE_CANTOPEN && !log_left && ::access(fs::path(path_).parent_path().c_str(), W_OK) != 0) {
    sqlite3_close(db_);
    db_ = nullptr;
    rc = sqlite3_open_v2((sqlite_uri(path_) + "?immutable=1").c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI,
                         nullptr);
    if (rc == SQLITE_OK) rc = probe();
    if (rc == SQLITE_OK) return;
  }
  fail(why);
}

void StudyDb::step_done(sqlite3_stmt* st) {
  const int rc = sqlite3_step(st);
  sqlite3_finalize(st);
  if (rc != SQLITE_DONE) fail(sqlite3_errmsg(db_));
}

void StudyDb::fail(const std::string& why) { throw UserError(path_ + ": " + why); }

StudyRow row_of(const StudyPoint& p, const std::string& status, const std::string& error,
                const nlohmann::ordered_json* report, StudyFailure failure) {
  std::vector<std::pair<std::string, nlohmann::ordered_json>> row = {
      {"point", p.hash}, {"point_index", p.index}, {"status", status}, {"error", error}};
  if (status != "ok") row.emplace_back("failure", to_string(failure));
  std::set<std::string> names = {"point", "point_index", "status", "error", "failure", "report"};
  const nlohmann::ordered_json params = p.params_json();
  for (auto it = params.begin(); it != params.end(); ++it) {
    row.emplace_back(it.key(), it.value());
    names.insert(it.key());
  }
  if (report) {
    row.emplace_back("report", report->dump());
    std::vector<std::pair<std::string, nlohmann::ordered_json>> m;
    flatten(*report, "", m);
    for (auto& [k, v] : m)
      if (names.insert(k).second) row.emplace_back(k, v);
  }
  return row;
}

FolderOutcome record_from_folder(StudyDb& db, const std::string& dir, const StudyPoint& p) {
  const fs::path pd = point_dir(dir, p);
  if (fs::exists(pd / "report.json")) {
    const nlohmann::ordered_json report = nlohmann::ordered_json::parse(read_whole_file(pd / "report.json"));
    auto row = row_of(p, "ok", "", &report);
    std::string ref = fs::exists(pd / "reference.txt") ? read_whole_file(pd / "reference.txt") : "";
    while (!ref.empty() && ref.back() == '\n') ref.pop_back();
    row.emplace_back("reference_key", ref);
    db.put_row(row);
    return FolderOutcome::kOk;
  }
  for (const auto& [file, kind] :
       {std::pair{"error.txt", StudyFailure::kInput}, {"host-error.txt", StudyFailure::kHost}})
    if (fs::exists(pd / file)) {
      db.put_row(row_of(p, "failed", recorded_error(pd / file), nullptr, kind));
      return kind == StudyFailure::kHost ? FolderOutcome::kHostFailure : FolderOutcome::kInputFailure;
    }
  return FolderOutcome::kNone;
}

std::string study_file_of(const std::string& dir) {
  const fs::path db_path = fs::path(dir) / "results.db";
  if (!fs::exists(db_path)) throw UserError(dir + ": not a study folder (no results.db)");
  const std::string file = StudyDb(db_path.string(), StudyDb::Mode::kRead).meta("file");
  if (file.empty()) throw UserError(dir + ": the database does not name its study file");
  return file;
}

StudyExport export_study_csv(const std::string& dir, const std::string& csv_path) {
  const fs::path db_path = fs::path(dir) / "results.db";
  if (!fs::exists(db_path)) throw UserError(dir + ": not a study folder (no results.db)");
  StudyDb db(db_path.string(), StudyDb::Mode::kRead);
  StudyExport ex;
  ex.study = db.meta("name");
  sqlite3_stmt* st = db.prepare("SELECT * FROM results ORDER BY point_index");
  const int n = sqlite3_column_count(st);
  auto csv = [](const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  std::string out;
  std::vector<int> cols;
  for (int c = 0; c < n; ++c)
    if (std::string(sqlite3_column_name(st, c)) != "report") cols.push_back(c);
  for (size_t i = 0; i < cols.size(); ++i) out += (i ? "," : "") + csv(sqlite3_column_name(st, cols[i]));
  out += "\n";
  ex.columns = cols.size();
  int status_col = -1;
  for (int c = 0; c < n; ++c)
    if (std::string(sqlite3_column_name(st, c)) == "status") status_col = c;
  while (sqlite3_step(st) == SQLITE_ROW) {
    ++ex.rows;
    if (status_col >= 0 && sqlite3_column_text(st, status_col))
      ++(std::string(reinterpret_cast<const char*>(sqlite3_column_text(st, status_col))) == "ok" ? ex.ok : ex.failed);
    for (size_t i = 0; i < cols.size(); ++i) {
      const int c = cols[i];
      std::string v;
      switch (sqlite3_column_type(st, c)) {
        case SQLITE_NULL:
          break;
        case SQLITE_INTEGER:
          v = std::to_string(sqlite3_column_int64(st, c));
          break;
        case SQLITE_FLOAT:
          v = fmt::format("{}", sqlite3_column_double(st, c));
          break;
        default:
          v = reinterpret_cast<const char*>(sqlite3_column_text(st, c));
      }
      out += (i ? "," : "") + csv(v);
    }
    out += "\n";
  }
  sqlite3_finalize(st);
  write_text_output(csv_path, out, true);
  return ex;
}

}  // namespace ropsim
