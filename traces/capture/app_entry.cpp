#include "traces/capture/app_entry.h"

#include <toml++/toml.h>

#include <filesystem>

#include "traces/capture/scene_file.h"
#include "traces/capture/toml_keys.h"
#include "traces/format/utf8.h"
#include "util/toml_guard.h"

namespace ropsim {

namespace {

using TomlKeys = detail::TomlKeys<CaptureError>;

bool valid_spp(int64_t s) { return s == 1 || s == 2 || s == 4 || s == 8 || s == 16 || s == 32 || s == 64; }

bool valid_target(const std::string& t) {
  if (t == "presented") return true;
  return t.rfind("fbo:", 0) == 0 && t.size() > 4 && t.size() < 14 &&
         t.find_first_not_of("0123456789", 4) == std::string::npos && std::stoull(t.substr(4)) > 0;
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
    s.replace(at, from.size(), to);
}

}  // namespace

AppEntry parse_app_entry(const std::string& text, const std::string& path, const AppOverrides& o) {
  const TomlInput in = toml_input(text, path);
  if (!in.error.empty()) throw CaptureError(in.error);
  toml::table root;
  try {
    root = toml::parse(in.ascii, path);
  } catch (const toml::parse_error& e) {
    throw CaptureError(path + ":" + std::to_string(e.source().begin.line) + ": " + std::string(e.description()));
  }
  TomlKeys top(root, path, "");
  const toml::table* app = top.table("app");
  if (!app) throw CaptureError(path + ": app: missing (an application entry is an [app] table)");
  top.finish();
  TomlKeys k(*app, path, "app.");
  AppEntry e;
  e.path = path;
  e.name = k.string("name").value_or(std::filesystem::path(path).stem().string());
  if (e.name.empty()) k.fail(k.node("name"), "name", "must not be empty");
  if (!is_valid_utf8(e.name))
    throw CaptureError(path + ": the file name is not valid UTF-8: give the entry a name (app.name = \"...\")");
  auto required = [&](const char* key) {
    if (!k.node(key)) k.fail(nullptr, key, "missing (required)");
  };
  required("package");
  e.package = *k.string("package");
  if (e.package.empty() || e.package.find_first_of(" \t/") != std::string::npos)
    k.fail(k.node("package"), "package", "must be one Debian package name");
  required("command");
  e.command = *k.strings("command");
  if (e.command[0].empty()) k.fail(k.node("command"), "command", "the program (its first element) is empty");
  required("frame");
  e.frame = *k.integer("frame");
  if (e.frame < 0) k.fail(k.node("frame"), "frame", "must be >= 0 (frames count from 0)");
  e.target = k.string("target").value_or("presented");
  if (!valid_target(e.target))
    k.fail(k.node("target"), "target", "\"" + e.target + "\" is not presented or fbo:N (N >= 1, an FBO's GL name)");
  auto size = [&](const char* key) {
    required(key);
    const int64_t v = *k.integer(key);
    if (v < 16 || v > 16384) k.fail(k.node(key), key, "must be in 16..16384 pixels");
    return unsigned(v);
  };
  e.width = size("width");
  e.height = size("height");
  e.spp = int(k.integer("spp").value_or(1));
  if (!valid_spp(k.integer("spp").value_or(1))) k.fail(k.node("spp"), "spp", "must be 1, 2, 4, 8, 16, 32 or 64");
  e.timeout = k.number_in("timeout", 120, 0.1, 1e6, "0.1..1e6 seconds");
  e.large = k.boolean("large").value_or(false);
  required("shows");
  e.shows = *k.string("shows");
  k.finish();

  if (o.spp) {
    if (!valid_spp(*o.spp))
      throw CaptureError(path + ": spp " + std::to_string(*o.spp) + ": must be 1, 2, 4, 8, 16, 32 or 64");
    e.spp = *o.spp;
  }
  for (auto [v, side] : {std::make_pair(o.width, &e.width), std::make_pair(o.height, &e.height)})
    if (v) {
      if (*v < 16 || *v > 16384)
        throw CaptureError(path + ": size " + std::to_string(*v) + ": must be in 16..16384 pixels");
      *side = *v;
    }
  if (o.frame) {
    if (*o.frame < 0) throw CaptureError(path + ": frame " + std::to_string(*o.frame) + ": must be >= 0");
    e.frame = *o.frame;
  }
  return e;
}

AppEntry load_app_entry(const std::string& path, const AppOverrides& o) {
  std::string text;
  if (!read_text_file(path, text)) throw CaptureError(path + ": cannot read the application entry file");
  return parse_app_entry(text, path, o);
}

std::vector<std::string> app_command(const AppEntry& e) {
  std::vector<std::string> argv = e.command;
  for (std::string& a : argv) {
    replace_all(a, "{width}", std::to_string(e.width));
    replace_all(a, "{height}", std::to_string(e.height));
  }
  return argv;
}

}  // namespace ropsim
