// Studies (docs/studies.md): a what-if sweep described in one TOML file --
// its inputs, its axes over any run parameter, how the axes combine, and the
// reference its quality metrics compare against -- expanded into points, each
// identified by a hash of its fully resolved parameters and the tool version.
// This file: the study file and its points; study_runner.h runs them.
#pragma once
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

#include "rtl_models/config/hw_config.h"
#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/functional/driver.h"
#include "sim/fidelity/sampled/livepoints.h"
#include "traces/capture/app_entry.h"
#include "traces/capture/scene_file.h"

namespace ropsim {

/// A parameter value: an integer, a real, a boolean or a string.
using StudyValue = std::variant<int64_t, double, bool, std::string>;
std::string to_string(const StudyValue& v);
nlohmann::ordered_json to_json(const StudyValue& v);

/// One input of a study: a built-in scene, a trace file, or a mesh scene file
/// or an application entry captured on demand.
struct StudyInput {
  /// The name the results use: the study's `name` for the entry when given,
  /// else the scene's own name (a built-in scene's, a mesh scene file's `name`
  /// key, a trace file's stem).
  std::string label;
  std::string scene;  ///< a built-in scene, or
  std::string trace;  ///< a trace file (absolute, resolved against the study file's folder), or
  std::string mesh;   ///< a mesh scene file (absolute), captured once per resolution, spp, seed and order, or
  std::string app;    ///< an application entry (absolute, traces/apps), captured once per resolution and spp
  std::string at;     ///< the study file's entry that names it, e.g. "inputs.meshes[1]"
  int line = 0;       ///< the line of that entry in the study file
};

/// The parameters of one named case: key -> value (run and hardware keys).
using StudyCase = std::map<std::string, StudyValue>;

struct StudyAxis {
  /// method, spp, seed, fidelity, hash_bits, ..., a hardware key
  /// "section.key", or "cases" (the named cases of axes.cases)
  std::string key;
  std::vector<StudyValue> values;  ///< for "cases": the cases' names
  std::vector<StudyCase> cases;    ///< for "cases": each case's parameters (values[i]'s)
  bool is_cases() const { return key == "cases"; }
};

/// The parameter under which a point of a named case records the case's name.
inline constexpr const char* kCaseParam = "case";

/// The [slurm] section: options of `study run --executor slurm`
/// (slurm_executor.h); the command line overrides them. Not part of any
/// point's identity.
struct StudySlurm {
  std::string partition;          ///< sbatch --partition ("" = the cluster's default)
  std::string time;               ///< sbatch --time, e.g. "00:30:00" ("" = the partition's default)
  std::string mem;                ///< sbatch --mem, e.g. "2G" ("" = the partition's default)
  unsigned throttle = 0;          ///< at most this many array tasks at once (0 = no limit)
  std::vector<std::string> args;  ///< extra sbatch arguments, e.g. "--qos=short"
};

struct Study {
  std::string path;  ///< the study file
  std::string name;
  enum class Combine { kProduct, kZip } combine = Combine::kProduct;
  std::vector<StudyInput> inputs;
  std::vector<StudyAxis> axes;
  /// Quality metrics against the A-buffer reference of the point's input
  /// (rendered once per input and resolution); at reference_spp samples per
  /// pixel when set (scenes only), else at the point's own spp.
  bool reference = true;
  int reference_spp = 0;
  bool save_images = false;  ///< each point's image as image.png in its folder
  StudySlurm slurm;
  /// Searched first for a mesh scene's meshes (`study run --mesh-dir`;
  /// absolute; "" = $ROPSIM_MESH_DIR, then the scene's mesh_dir). Not part
  /// of any point's identity.
  std::string mesh_dir;
  /// Inputs x axes (before functional points are deduplicated), as counted
  /// by parse_study (at most kMaxStudyPoints).
  uint64_t points_at_most = 0;
};

/// The most points a study may have (inputs x axes, before functional points
/// are deduplicated); a study file with more is refused.
inline constexpr uint64_t kMaxStudyPoints = 100000;

/// Reads and checks a study file. Every unknown key and bad value throws
/// UserError "FILE: KEY: reason" before anything runs. mesh_dir: as
/// Study::mesh_dir (made absolute).
Study load_study(const std::string& path, const std::string& mesh_dir = "");
/// load_study of a study file's text; path names it in errors and locates
/// the files it names relative to its folder.
Study parse_study(const std::string& text, const std::string& path, const std::string& mesh_dir = "");

/// Checks that every file the study's inputs need is there: each mesh scene's
/// meshes, textures and OBJ material libraries (looked up as `ropsim capture
/// --mesh-dir` does, with s.mesh_dir) and each trace. load_study checked the
/// scene files, the traces and the design files; this is what a capture
/// would find missing only when it ran. Throws UserError "FILE: ENTRY (line
/// N): reason" naming the study file's entry of the first input that lacks
/// a file.
void check_study_inputs(const Study& s);

/// A point of a study: one run's parameters.
struct StudyPoint {
  size_t index = 0;                          ///< in expansion order
  std::string hash;                          ///< 16 hex digits of the resolved parameters and the tool version
  std::string input;                         ///< the input's label
  std::map<std::string, StudyValue> params;  ///< every axis value, by key (input included)
  nlohmann::ordered_json params_json() const;
};

/// The points of a study, in a fixed order: inputs outermost, then the axes
/// in file order (product), or the axes' i-th values together, a one-value
/// axis with every position (zip). A named case is one value of the axis
/// "cases": its parameters and its name (kCaseParam) together.
std::vector<StudyPoint> expand_study(const Study& s);

/// What a point runs: the input, the method, the fidelity and the design.
/// Throws UserError (e.g. a cache shape only this combination breaks).
struct ResolvedPoint {
  std::string capture_key;             ///< mesh and app inputs: the capture, DIR/traces/<key>.rtr ("" otherwise)
  std::string capture_scene;           ///< mesh inputs: the scene file
  SceneOverrides capture_overrides;    ///< mesh inputs: spp, resolution, seed and draw order
  std::string capture_app;             ///< app inputs: the application entry
  AppOverrides capture_app_overrides;  ///< app inputs: spp and resolution
  InputSpec input;
  MethodConfig method;
  Fidelity fidelity = Fidelity::kFunctional;
  bool timed() const { return is_timed(fidelity); }
  HwConfig hw;                 ///< timed fidelities: the design
  SamplingParams sampling;     ///< sampled: the defaults
  std::string livepoints_key;  ///< sampled: its live-point library, DIR/livepoints/<key>.rlp
  std::string reference_key;   ///< "" when the study has no reference
  InputSpec reference_input;   ///< the input the reference is rendered from
};
/// dir: the study folder, where a mesh input's capture is (traces/<key>.rtr).
ResolvedPoint resolve_point(const Study& s, const StudyPoint& p, const std::string& dir = "");

}  // namespace ropsim
