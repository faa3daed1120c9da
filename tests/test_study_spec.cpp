// The study file (docs/studies.md "The study file"): what it can say and how
// it expands -- zip with repeated and single values, named cases crossed or
// zipped with the other axes, inputs named by their scenes, every input's
// files checked before anything runs (and `study run --mesh-dir`), every
// shipped study loading -- and the report's equal-quality table, which
// interpolates between the swept spp.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "sim/study/study.h"
#include "tests/study_test_util.h"

namespace fs = std::filesystem;
using namespace ropsim_test;

namespace {

/// The points of a study file's text, as "key=value, ..." (input first).
std::vector<std::string> points_of(const ropsim::Study& s) {
  std::vector<std::string> out;
  for (const auto& p : ropsim::expand_study(s)) {
    std::string t = "input=" + p.input;
    for (const auto& [k, v] : p.params) t += ", " + k + "=" + ropsim::to_string(v);
    out.push_back(t);
  }
  return out;
}

std::vector<std::string> points_of(const std::string& text, const std::string& path = "spec.toml") {
  return points_of(ropsim::parse_study(text, path));
}

/// The error parse_study gives for text ("" when it gives none).
std::string error_of(const std::string& text, const std::string& path = "spec.toml") {
  try {
    ropsim::parse_study(text, path);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

const std::string kSource = ROPSIM_SOURCE_DIR;

}  // namespace

// "lk at 16 spp against enderton at 64", written as zipped lists: a value may
// stand at several positions, and a single value goes with every position.
TEST(StudySpec, ZipTakesRepeatedValuesAndBroadcastsSingleValues) {
  const std::string text = R"(
[study]
combine = "zip"
[inputs]
scenes = ["cloth"]
[axes]
method = ["lk", "enderton", "lk"]
spp = [16, 64, 64]
seed = 2
width = [32]
)";
  std::vector<std::string> got;
  ASSERT_NO_THROW(got = points_of(text)) << error_of(text);
  const std::vector<std::string> want = {
      "input=cloth, method=lk, seed=2, spp=16, width=32",
      "input=cloth, method=enderton, seed=2, spp=64, width=32",
      "input=cloth, method=lk, seed=2, spp=64, width=32",
  };
  EXPECT_EQ(got, want);
  EXPECT_EQ(ropsim::parse_study(text, "spec.toml").points_at_most, 3u);
}

TEST(StudySpec, ZipRefusesListsOfOtherLengthsAndOneCombinationTwice) {
  const std::string head = "[study]\ncombine = \"zip\"\n[inputs]\nscenes = [\"cloth\"]\n[axes]\n";
  const std::string lengths = error_of(head + "method = [\"lk\", \"enderton\", \"naive\"]\nspp = [4, 8]\n");
  EXPECT_NE(lengths.find("spec.toml: axes.spp: combine = \"zip\" needs lists of one length"), std::string::npos)
      << lengths;
  const std::string twice = error_of(head + "method = [\"lk\", \"enderton\", \"lk\"]\nspp = [4, 8, 4]\n");
  EXPECT_NE(twice.find("spec.toml: axes: combine = \"zip\": positions 1 and 3"), std::string::npos) << twice;
  // Under product a value twice is still a mistake.
  const std::string product = error_of("[inputs]\nscenes = [\"cloth\"]\n[axes]\nspp = [4, 4]\n");
  EXPECT_NE(product.find("spec.toml: axes.spp: the value 4 appears twice"), std::string::npos) << product;
}

// Named cases are one axis: crossed with the others under product, in file
// order, each point keeping its case's name.
TEST(StudySpec, NamedCasesCrossWithTheOtherAxesAndKeepTheirNames) {
  const std::string text = R"(
[inputs]
scenes = ["cloth"]
[axes]
seed = [1, 2]
cases = [{name = "lk16", method = "lk", spp = 16}, {name = "enderton64", method = "enderton", spp = 64}]
width = 32
)";
  std::vector<std::string> got;
  ASSERT_NO_THROW(got = points_of(text)) << error_of(text);
  const std::vector<std::string> want = {
      "input=cloth, case=lk16, method=lk, seed=1, spp=16, width=32",
      "input=cloth, case=enderton64, method=enderton, seed=1, spp=64, width=32",
      "input=cloth, case=lk16, method=lk, seed=2, spp=16, width=32",
      "input=cloth, case=enderton64, method=enderton, seed=2, spp=64, width=32",
  };
  EXPECT_EQ(got, want);
  // [[axes.cases]] tables are the same cases, at the place of the first.
  const std::string tables = R"(
[inputs]
scenes = ["cloth"]
[axes]
seed = [1, 2]
width = 32
[[axes.cases]]
name = "lk16"
method = "lk"
spp = 16
[[axes.cases]]
name = "enderton64"
method = "enderton"
spp = 64
)";
  ASSERT_NO_THROW(got = points_of(tables)) << error_of(tables);
  EXPECT_EQ(got, want);
}

TEST(StudySpec, NamedCasesZipWithTheOtherListsPositionByPosition) {
  const std::string text = R"(
[study]
combine = "zip"
[inputs]
scenes = ["cloth"]
[axes]
cases = [{name = "lk16", method = "lk", spp = 16}, {name = "enderton64", method = "enderton", spp = 64},
         {name = "hashed", method = "hashed"}]
seed = [1, 2, 3]
width = 32
)";
  std::vector<std::string> got;
  ASSERT_NO_THROW(got = points_of(text)) << error_of(text);
  const std::vector<std::string> want = {
      "input=cloth, case=lk16, method=lk, seed=1, spp=16, width=32",
      "input=cloth, case=enderton64, method=enderton, seed=2, spp=64, width=32",
      "input=cloth, case=hashed, method=hashed, seed=3, width=32",
  };
  EXPECT_EQ(got, want);
}

TEST(StudySpec, BadCasesAreRefusedNamingTheCaseAndKey) {
  const std::string head = "[inputs]\nscenes = [\"cloth\"]\n[axes]\n";
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"cases = [{method = \"lk\"}]", "axes.cases[0]: missing name"},
      {"cases = [{name = \"a\", method = \"lk\"}, {name = \"a\", method = \"enderton\"}]",
       "axes.cases[1].name: two cases are named a"},
      {"cases = [{name = \"a\", method = \"lk\"}, {name = \"b\", method = \"lk\"}]",
       "axes.cases[1]: sets the parameters of axes.cases[0]"},
      {"cases = [{name = \"a\", spp = [4, 16]}]", "axes.cases[0].spp: a case is one combination"},
      {"cases = [{name = \"a\", spp = 3}]", "axes.cases[0].spp: 3 is not a power of two"},
      {"cases = [{name = \"a\", methd = \"lk\"}]", "axes.cases[0].methd: unknown parameter"},
      {"spp = [4, 16]\ncases = [{name = \"a\", spp = 64}]", "axes.spp: is set by axes.cases[0] too"},
      {"cases = [{name = \"a\", \"cache.ways\" = 4}]", "axes: hardware keys need a timed fidelity"},
      {"cases = \"lk\"", "axes.cases: expected a list of tables"},
      {"cases = []", "axes.cases: expected a list of tables"},
  };
  for (const auto& [axes, why] : bad) {
    const std::string e = error_of(head + axes + "\n");
    EXPECT_NE(e.find("spec.toml: " + why), std::string::npos) << axes << "\n gave: " << e;
  }
  // A case may take a design and hardware keys with a timed fidelity.
  const std::string hw = head +
                         "cases = [{name = \"c4\", fidelity = \"cycle\", \"distributor.rop_units\" = 4}, "
                         "{name = \"f\", fidelity = \"functional\"}]\n";
  EXPECT_EQ(error_of(hw), "");
}

// A point of a case records the case's name in its database row (column
// `case`), beside its other parameters.
TEST(StudySpec, ACasesNameIsAColumnOfItsPointsRows) {
  Scratch s;
  s.put("cases.toml", R"(
[inputs]
scenes = ["cloth"]
[axes]
cases = [{name = "lk16", method = "lk", spp = 16}, {name = "enderton64", method = "enderton", spp = 64}]
width = 24
height = 24
)");
  const Ran r = ropsim_test::ropsim(s.dir, "study run cases.toml --out st -j 1 --quiet");
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  const Rows rows = export_rows(s.dir, "st");
  ASSERT_EQ(rows.size(), 2u);
  std::map<std::string, std::pair<std::string, std::string>> by_case;
  for (const auto& row : rows) by_case[row.at("case")] = {row.at("method"), row.at("spp")};
  EXPECT_EQ(by_case["lk16"], std::make_pair(std::string("lk"), std::string("16")));
  EXPECT_EQ(by_case["enderton64"], std::make_pair(std::string("enderton"), std::string("64")));
}

// An input is named by its scene: a built-in scene's name, a mesh scene
// file's `name` key, a trace's stem; or by the entry's own `name`.
TEST(StudySpec, InputsAreNamedByTheirScenesOrByTheirEntry) {
  Scratch s;
  const std::string cloth = kSource + "/traces/scenes/mesh/cloth.toml";
  ASSERT_EQ(ropsim_test::ropsim(s.dir, "scene cloth --spp 4 --width 16 --height 16 -o cloth.rtr").status, 0);
  auto labels = [&](const std::string& inputs) {
    const ropsim::Study st = ropsim::parse_study("[inputs]\n" + inputs, (s.dir / "n.toml").string());
    std::vector<std::string> l;
    for (const auto& in : st.inputs) l.push_back(in.label);
    std::sort(l.begin(), l.end());
    return l;
  };
  using V = std::vector<std::string>;
  // The mesh scene names itself "cloth-mesh", alone or beside the built-in cloth.
  EXPECT_EQ(labels("meshes = [\"" + cloth + "\"]\n"), V{"cloth-mesh"});
  EXPECT_EQ(labels("scenes = [\"cloth\"]\nmeshes = [\"" + cloth + "\"]\n"), (V{"cloth", "cloth-mesh"}));
  EXPECT_EQ(labels("traces = [\"cloth.rtr\"]\nmeshes = [\"" + cloth + "\"]\n"), (V{"cloth", "cloth-mesh"}));
  EXPECT_EQ(labels("meshes = [{path = \"" + cloth +
                   "\", name = \"sheet\"}]\nscenes = [{scene = \"smoke\", name = "
                   "\"puff\"}]\ntraces = [{path = \"cloth.rtr\", name = \"c4\"}]\n"),
            (V{"c4", "puff", "sheet"}));
  // Two inputs of one name: refused, naming both entries.
  const std::string twice =
      error_of("[inputs]\nscenes = [\"cloth\"]\ntraces = [\"cloth.rtr\"]\n", (s.dir / "n.toml").string());
  EXPECT_NE(twice.find("n.toml: inputs.traces[0]: two inputs are named cloth (inputs.scenes[0] too)"),
            std::string::npos)
      << twice;
  const std::string key = error_of("[inputs]\nmeshes = [{file = \"" + cloth + "\"}]\n", (s.dir / "n.toml").string());
  EXPECT_NE(key.find("n.toml: inputs.meshes[0].file: unknown key (path, name)"), std::string::npos) << key;
}

// Every study in studies/ loads and expands (without its meshes: they are
// checked only by study run), and an input has one name in all of them.
TEST(StudySpec, EveryShippedStudyLoadsExpandsAndNamesEachInputOnce) {
  std::map<std::string, std::pair<std::string, std::string>> name_of;  // the input -> (its name, the study)
  size_t studies = 0;
  for (const auto& e : fs::directory_iterator(kSource + "/studies")) {
    if (e.path().extension() != ".toml") continue;
    ++studies;
    const std::string f = e.path().string();
    ropsim::Study st;
    try {
      st = ropsim::load_study(f);
    } catch (const std::exception& ex) {
      ADD_FAILURE() << f << " does not load: " << ex.what();
      continue;
    }
    const std::vector<ropsim::StudyPoint> points = ropsim::expand_study(st);
    EXPECT_FALSE(points.empty()) << f;
    EXPECT_LE(points.size(), st.points_at_most) << f;
    for (const auto& in : st.inputs) {
      const std::string what = !in.scene.empty()  ? "scene " + in.scene
                               : !in.mesh.empty() ? "mesh " + fs::path(in.mesh).lexically_normal().string()
                               : !in.app.empty()  ? "app " + fs::path(in.app).lexically_normal().string()
                                                  : "trace " + fs::path(in.trace).lexically_normal().string();
      const auto [it, fresh] = name_of.emplace(what, std::make_pair(in.label, e.path().filename().string()));
      EXPECT_EQ(in.label, it->second.first) << what << " is named " << in.label << " in " << e.path().filename()
                                            << " but " << it->second.first << " in " << it->second.second;
    }
  }
  EXPECT_GE(studies, 10u) << "the shipped studies were not found in " << kSource << "/studies";
}

// A study's missing inputs are refused before any point runs: one line naming
// the study file and the entry (and its line), exit 1, no study folder.
TEST(StudySpec, AMissingMeshIsRefusedBeforeAnyPointRuns) {
  Scratch s;
  const std::string mesh_folder = kSource + "/traces/scenes/mesh";
  // A scene file whose mesh is in neither its mesh_dir nor --mesh-dir.
  fs::create_directories(s.dir / "scenes");
  s.put("scenes/sheet.toml", R"(
name = "sheet"
width = 32
height = 24
mesh_dir = "../nowhere"
[camera]
eye = [0.0, 0.35, 2.6]
target = [0.03, 0.03, 0.0]
fov_y = 40.0
near = 1.0
far = 5.0
[[object]]
name = "cloth"
mesh = "cloth.obj"
opacity = 0.4
)");
  s.put("m.toml", R"([inputs]
scenes = ["cloth"]
meshes = ["scenes/sheet.toml"]

[axes]
method = ["lk", "enderton"]
spp = 4
width = 32
height = 24
)");
  for (const std::string verb : {"run", "plan"}) {
    const Ran r = ropsim_test::ropsim(s.dir, "study " + verb + " m.toml --out st");
    EXPECT_EQ(r.status, 1) << verb << ": " << r.err;
    EXPECT_NE(r.err.find("ropsim: error: m.toml: inputs.meshes[0] (line 3): "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("nowhere/cloth.obj: no such mesh file"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "one line:\n" << r.err;
    EXPECT_FALSE(fs::exists(s.dir / "st")) << "study " << verb << " made a folder (points, results.db) before "
                                           << "it knew a mesh was missing";
  }
  // --mesh-dir names the folder of the meshes, as for ropsim capture.
  const Ran ok = ropsim_test::ropsim(s.dir, "study run m.toml --out st -j 1 --quiet --mesh-dir '" + mesh_folder + "'");
  ASSERT_EQ(ok.status, 0) << ok.err << ok.out;
  const Rows rows = export_rows(s.dir, "st");
  EXPECT_EQ(rows.size(), 4u);
  for (const auto& row : rows) EXPECT_EQ(row.at("status"), "ok") << row.at("error");
  // A mesh whose material library is missing is refused the same way.
  fs::create_directories(s.dir / "nomtl");
  fs::copy_file(mesh_folder + "/cloth.obj", s.dir / "nomtl" / "cloth.obj");
  const Ran mtl = ropsim_test::ropsim(s.dir, "study run m.toml --out st2 -j 1 --mesh-dir nomtl");
  EXPECT_EQ(mtl.status, 1) << mtl.err;
  EXPECT_NE(mtl.err.find("m.toml: inputs.meshes[0] (line 3): "), std::string::npos) << mtl.err;
  EXPECT_NE(mtl.err.find("nomtl/cloth.mtl: no such file"), std::string::npos) << mtl.err;
  EXPECT_FALSE(fs::exists(s.dir / "st2"));
}

// --mesh-dir reaches the tasks of another executor: the cluster's batch
// scripts pass it to `study task`, whose capture then finds the mesh. Fake
// sbatch and squeue stand for the cluster.
TEST(StudySpec, TheMeshDirReachesTheClustersTasks) {
  Scratch s;
  const std::string mesh_folder = kSource + "/traces/scenes/mesh";
  fs::create_directories(s.dir / "bin");
  s.put("bin/sbatch", "#!/bin/sh\nn=$(cat '" + s.dir.string() + "/n' 2>/dev/null || echo 0); echo $((n + 1)) > '" +
                          s.dir.string() + "/n'\necho $((n + 1))\n");
  s.put("bin/squeue", "#!/bin/sh\nexit 0\n");
  for (const char* t : {"sbatch", "squeue"}) fs::permissions(s.dir / "bin" / t, fs::perms::owner_all);
  fs::create_directories(s.dir / "scenes");
  s.put("scenes/sheet.toml", R"(
name = "sheet"
mesh_dir = "../nowhere"
[camera]
eye = [0.0, 0.35, 2.6]
target = [0.03, 0.03, 0.0]
fov_y = 40.0
near = 1.0
far = 5.0
[[object]]
mesh = "cloth.obj"
opacity = 0.4
)");
  s.put("m.toml", "[inputs]\nmeshes = [\"scenes/sheet.toml\"]\n[axes]\nspp = 4\nwidth = 32\nheight = 24\n");
  const Ran r =
      shell(s.dir, "env PATH='" + (s.dir / "bin").string() +
                       ":/usr/bin:/bin' '" ROPSIM_BINARY "' study run m.toml --out st --executor slurm --mesh-dir '" +
                       mesh_folder + "'");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const std::string script = slurp(s.dir / "st" / "slurm" / "captures.sbatch");
  EXPECT_NE(script.find(" --mesh-dir '" + mesh_folder + "'"), std::string::npos) << script;
  // The task the script runs, as a node would run it.
  const Ran task =
      ropsim_test::ropsim(s.dir, "study task m.toml --out st --kind c --index 0 --mesh-dir '" + mesh_folder + "'");
  EXPECT_EQ(task.status, 0) << task.err;
  size_t traces = 0;
  for (const auto& e : fs::directory_iterator(s.dir / "st" / "traces")) traces += e.path().extension() == ".rtr";
  EXPECT_EQ(traces, 1u) << "the capture did not find the mesh in --mesh-dir";
}

// ropsim ignores SIGPIPE (its writers report EPIPE themselves), and an
// ignored signal survives exec: the cluster's commands must start with it at
// its default, or a pipeline inside them would not end when its reader does.
TEST(StudySpec, TheClustersCommandsStartWithSigpipeAtItsDefault) {
  Scratch s;
  fs::create_directories(s.dir / "bin");
  s.put("bin/sbatch", "#!/bin/sh\ngrep SigIgn /proc/$$/status > '" + s.dir.string() + "/sigign'\necho 1\n");
  s.put("bin/squeue", "#!/bin/sh\nexit 0\n");
  for (const char* t : {"sbatch", "squeue"}) fs::permissions(s.dir / "bin" / t, fs::perms::owner_all);
  s.put("m.toml", "[inputs]\nscenes = [\"smoke\"]\n[axes]\nspp = 4\n");
  const Ran r = shell(s.dir, "env PATH='" + (s.dir / "bin").string() +
                                 ":/usr/bin:/bin' '" ROPSIM_BINARY "' study run m.toml --out st --executor slurm");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const std::string line = slurp(s.dir / "sigign");
  ASSERT_EQ(line.rfind("SigIgn:", 0), 0u) << "sbatch did not run: " << line;
  const unsigned long long ignored = std::stoull(line.substr(7), nullptr, 16);
  EXPECT_EQ(ignored & (1ull << (SIGPIPE - 1)), 0u) << "sbatch started with SIGPIPE ignored: " << line;
  EXPECT_EQ(ignored & (1ull << (SIGXFSZ - 1)), 0u) << "sbatch started with SIGXFSZ ignored: " << line;
}

// A glTF's external buffer is one of its mesh's files.
TEST(StudySpec, AGltfsMissingBufferIsRefusedByTheInputCheck) {
  Scratch s;
  s.put("tri.gltf", R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "tri%20data.bin", "byteLength": 36}]})");
  s.put("scene.toml", R"(
name = "tri"
[camera]
eye = [0, 0, 3]
target = [0, 0, 0]
[[object]]
mesh = "tri.gltf"
)");
  const ropsim::Study st = ropsim::parse_study("[inputs]\nmeshes = [\"scene.toml\"]\n", (s.dir / "g.toml").string());
  std::string e;
  try {
    ropsim::check_study_inputs(st);
  } catch (const std::exception& ex) {
    e = ex.what();
  }
  EXPECT_NE(e.find("g.toml: inputs.meshes[0] (line 2): "), std::string::npos) << e;
  EXPECT_NE(e.find("tri data.bin: no such file"), std::string::npos) << e;
  s.put("tri data.bin", std::string(36, '\0'));
  EXPECT_NO_THROW(ropsim::check_study_inputs(st));
}

namespace {

/// A study folder's results.db with functional points of two methods whose
/// RMSE follows c / sqrt(spp) exactly at spp 4, 16 and 64 (so that log RMSE
/// is linear in log2 spp, and the interpolated spp of a target t is
/// (c / t)^2), and state bytes 1010 spp.
void write_power_law_study(const fs::path& dir, const std::map<std::string, double>& c_of) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "results.db").string().c_str(), &db), SQLITE_OK);
  std::string sql =
      "CREATE TABLE results (point TEXT PRIMARY KEY, point_index INTEGER, status TEXT, error TEXT, report TEXT, "
      "input TEXT, method TEXT, spp INTEGER, \"vs_reference.rmse_8bit\" REAL, \"counters.state_bytes_read\" INTEGER, "
      "\"counters.state_bytes_written\" INTEGER);"
      "CREATE TABLE study (key TEXT PRIMARY KEY, value TEXT);"
      "INSERT INTO study VALUES ('name', 'power-law'), ('points', '6');";
  int i = 0;
  for (const auto& [method, c] : c_of)
    for (int spp : {4, 16, 64}) {
      sql += "INSERT INTO results VALUES ('p" + std::to_string(i) + "', " + std::to_string(i) + ", 'ok', '', '{}', " +
             "'cloth', '" + method + "', " + std::to_string(spp) + ", " + std::to_string(c / std::sqrt(spp)) + ", " +
             std::to_string(1000 * spp) + ", " + std::to_string(10 * spp) + ");";
      ++i;
    }
  char* err = nullptr;
  EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err), SQLITE_OK) << (err ? err : "");
  sqlite3_free(err);
  sqlite3_close(db);
  std::ofstream(dir / "study.toml") << "[inputs]\nscenes = [\"cloth\"]\n[axes]\nmethod = [\"lk\", \"enderton\"]\n"
                                       "spp = [4, 16, 64]\n";
}

/// The cells of a Markdown table row ("| a | b |" -> {"a", "b"}).
std::vector<std::string> md_cells(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream ss(line);
  std::string c;
  std::getline(ss, c, '|');  // before the first |
  while (std::getline(ss, c, '|')) {
    const size_t b = c.find_first_not_of(' '), e = c.find_last_not_of(' ');
    cells.push_back(b == std::string::npos ? "" : c.substr(b, e - b + 1));
  }
  return cells;
}

}  // namespace

// The equal-quality table finds the spp at which a method reaches a target
// RMSE between the swept spp (log RMSE linear in log2 spp), and says when a
// target is outside the swept range instead of giving a swept spp.
TEST(StudySpec, EqualQualityInterpolatesTheSppBetweenTheSweptPoints) {
  Scratch s;
  const std::map<std::string, double> c_of = {{"lk", 8.0}, {"enderton", 12.0}};
  write_power_law_study(s.dir, c_of);
  const Ran r = shell(s.dir, "/usr/bin/python3 '" + kSource + "/analysis/study_report.py' .");
  ASSERT_EQ(r.status, 0) << r.err;
  std::stringstream md(slurp(s.dir / "report" / "summary.md"));
  std::map<std::pair<std::string, std::string>, std::vector<std::string>> row;  // (target, curve) -> cells
  bool in_section = false;
  for (std::string line; std::getline(md, line);) {
    if (line.rfind("## ", 0) == 0) in_section = line == "## Equal quality";
    if (in_section && line.rfind("| cloth |", 0) == 0) {
      const std::vector<std::string> c = md_cells(line);
      ASSERT_GE(c.size(), 4u) << line;
      row[{c[1], c[2]}] = c;
    }
  }
  // The targets are lk's RMSE at each spp x 1.02 (3 digits): 4.08, 2.04, 1.02.
  const std::vector<std::string> targets = {"4.08", "2.04", "1.02"};
  ASSERT_EQ(row.size(), 6u) << slurp(s.dir / "report" / "summary.md");
  for (const auto& t : targets)
    for (const auto& [method, c] : c_of) {
      ASSERT_TRUE(row.count({t, method})) << t << " " << method;
      const std::string spp = row[{t, method}][3];
      const double want = std::pow(c / std::stod(t), 2);  // c / sqrt(spp) = t
      if (want < 4) {
        EXPECT_NE(spp.find("outside the swept range"), std::string::npos)
            << method << " reaches " << t << " at " << want << " spp, below 4: " << spp;
      } else if (want > 64) {
        EXPECT_NE(spp.find("outside the swept range"), std::string::npos)
            << method << " reaches " << t << " at " << want << " spp, above 64: " << spp;
      } else {
        EXPECT_NEAR(std::stod(spp), want, want * 0.005) << method << " at RMSE " << t << ": " << spp;
      }
    }
}
