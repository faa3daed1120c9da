// What a study file's keys and values mean, shared by the parser
// (study_parse.cpp) and the points (study.cpp): which keys are hardware,
// timed fidelities, the design files' paths, the zip combination, and the
// hash that names a point.
#pragma once
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "sim/study/study.h"
#include "util/hex.h"

namespace ropsim::study_detail {

bool is_sampling_key(const std::string& k);
/// Does the fidelity a study value names give time (and so take a design)?
bool is_timed(const std::string& f);
bool is_hw_key(const std::string& k);
/// A hardware key, or `design`.
bool is_hardware(const std::string& k);
/// Throws UserError "<study file>: <key>: <why>".
[[noreturn]] void fail(const Study& s, const std::string& key, const std::string& why);
/// A design file's path, relative to the study file's folder.
std::string design_path(const Study& s, const std::string& f);
/// A file's whole text ("" when it cannot be read).
std::string read_text(const std::string& path);
/// The overrides a study gives its mesh scenes' files: the folder of the meshes.
SceneOverrides scene_overrides(const Study& s);
/// Sets axis a's i-th value in m: a value, or a case's name and parameters.
void put_value(StudyCase& m, const StudyAxis& a, size_t i);
/// combine = "zip": the number of positions (the longest list; 1 when every
/// axis is a single value).
size_t zip_length(const Study& s);
/// combine = "zip": the parameters at position i (a single value at every position).
StudyCase zip_position(const Study& s, size_t i);
nlohmann::ordered_json to_json_params(const StudyCase& c);
bool is_regular_file(const std::string& p);
/// The hash of a text a point's identity is made of (printed with hex64).
uint64_t hash_text(const std::string& s);

}  // namespace ropsim::study_detail
