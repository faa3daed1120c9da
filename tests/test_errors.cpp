// One error hierarchy, one rule (util/errors.h, README "Exit status"): every
// user-facing error type is a UserError and maps to exit status 1, a broken
// invariant maps to 2, and main, a study's workers and a sampled run's
// live-point workers all report by that rule.
#include <gtest/gtest.h>

#include <algorithm>
#include <new>
#include <stdexcept>
#include <string>
#include <system_error>

#include "rtl_models/config/hw_config.h"
#include "rtl_models/functional/functional_rop.h"
#include "sim/driver/vectors.h"
#include "sim/image/image_io.h"
#include "tests/study_test_util.h"
#include "traces/capture/scene_file.h"
#include "traces/format/trace.h"
#include "traces/raster/sample_patterns.h"
#include "traces/scenes/scenes.h"
#include "util/codec/image_codec.h"
#include "util/errors.h"

namespace {

using namespace ropsim;
namespace fs = std::filesystem;
using ropsim_test::Ran;
using ropsim_test::Scratch;

/// The rule's verdict on a thrown e.
template <typename E>
ErrorVerdict verdict_of_thrown(const E& e) {
  try {
    throw e;
  } catch (...) {
    return classify_current_exception();
  }
}

/// Checks that E, constructed with a message, is a user error by the rule:
/// status 1 both ways of asking, its text kept, said as "error: <text>".
template <typename E, typename... Extra>
void expect_user_error(const char* type, Extra... extra) {
  SCOPED_TRACE(type);
  const E e(std::string(type) + ": bad.input: key x", extra...);
  const UserError* as_user = &e;  // compiles only if E derives from UserError
  EXPECT_NE(as_user, nullptr);
  EXPECT_EQ(exit_status_of(e), 1) << type << " is not classified as a user error (exit 1)";
  const ErrorVerdict v = verdict_of_thrown(e);
  EXPECT_EQ(v.status, 1) << type << " thrown is not classified as a user error (exit 1)";
  EXPECT_EQ(v.what, std::string(type) + ": bad.input: key x") << type << "'s message was not kept";
  EXPECT_EQ(v.message(), "error: " + std::string(type) + ": bad.input: key x")
      << type << " is not said in the one-line user error form";
}

TEST(Errors, EveryUserFacingErrorTypeIsAUserErrorWithExitStatus1) {
  expect_user_error<UserError>("UserError");
  expect_user_error<SystemError>("SystemError", 28);
  expect_user_error<TraceError>("TraceError");
  expect_user_error<ConfigError>("ConfigError");
  expect_user_error<SceneError>("SceneError");
  expect_user_error<CaptureError>("CaptureError");
  expect_user_error<ImageError>("ImageError");
  expect_user_error<ImageCodecError>("ImageCodecError");
  expect_user_error<VectorError>("VectorError");
}

TEST(Errors, SystemErrorKeepsItsErrno) {
  const SystemError e("out.png: No space left on device", 28);
  EXPECT_EQ(e.error_number(), 28) << "SystemError lost the errno it carries";
  EXPECT_EQ(exit_status_of(e), 1) << "a SystemError is a user (environment) error";
}

TEST(Errors, ABrokenInvariantHasExitStatus2) {
  const InternalError e("retired tokens <= issued tokens");
  EXPECT_EQ(exit_status_of(e), 2) << "an InternalError is not classified as a broken invariant (exit 2)";
  const ErrorVerdict v = verdict_of_thrown(e);
  EXPECT_EQ(v.status, 2) << "a thrown InternalError is not classified as exit 2";
  EXPECT_EQ(v.message(), "internal error: retired tokens <= issued tokens: please report it")
      << "the broken invariant is not said in the one-line internal error form";
  try {
    invariant(false, "a ROP's tiles are its own");
    ADD_FAILURE() << "invariant(false, ...) did not throw";
  } catch (...) {
    const ErrorVerdict w = classify_current_exception();
    EXPECT_EQ(w.status, 2) << "invariant(false) does not give exit status 2";
    EXPECT_EQ(w.what, "a ROP's tiles are its own") << "invariant() must name the invariant";
  }
  EXPECT_NO_THROW(invariant(true, "holds"));
}

TEST(Errors, TheRuleOnWhatIsNotOurs) {
  EXPECT_EQ(verdict_of_thrown(std::bad_alloc()).status, 1) << "running out of memory is the host's, exit 1";
  EXPECT_EQ(verdict_of_thrown(std::bad_alloc()).message(), "error: out of memory");
  EXPECT_EQ(verdict_of_thrown(std::system_error(std::make_error_code(std::errc::no_space_on_device), "x")).status, 1)
      << "a system_error (the host refused an operation) is a user error";
  EXPECT_EQ(verdict_of_thrown(std::logic_error("x")).status, 2) << "an unexpected std::logic_error is a bug";
  EXPECT_EQ(verdict_of_thrown(std::runtime_error("x")).status, 2)
      << "a bare std::runtime_error escaped the code that should have made it a UserError: a bug";
  EXPECT_EQ(verdict_of_thrown(std::invalid_argument("x")).status, 2)
      << "a bare std::invalid_argument escaped the code that should have made it a UserError: a bug";
  EXPECT_EQ(verdict_of_thrown(42).status, 2) << "an unknown exception is a bug";
  EXPECT_EQ(verdict_of_thrown(42).what, "an unknown exception");
  EXPECT_EQ(verdict_of_thrown(UserError("line one\nline two\n")).what, "line one line two")
      << "the verdict's text must be one line";
}

// Errors the library layers throw for bad requests, and the ones that are
// invariants, by the rule.
TEST(Errors, LibraryThrowsAreClassifiedByTheirCause) {
  EXPECT_THROW(make_vectors("bogus", 1, 1, Numerics{}), VectorError) << "an unknown vector unit is a user error";
  EXPECT_THROW(standard_sample_positions(3), UserError) << "3 spp has no standard pattern: a bad input";
  TraceHeader h;
  h.width = 16;
  h.height = 16;
  h.spp = 4;
  h.positions = standard_sample_positions(4);
  MethodConfig cfg;
  cfg.method = Method::kLk;
  FunctionalRop rop(h, cfg);
  EXPECT_NO_THROW(rop.begin_pass(0));
  EXPECT_THROW(rop.begin_pass(rop.passes()), InternalError) << "begin_pass past the method's passes is a bug";
  EXPECT_THROW(rop.begin_pass(-1), InternalError) << "begin_pass(-1) is a bug";
  cfg.method = Method::kReference;
  EXPECT_THROW(FunctionalRop(h, cfg), UserError) << "the reference method has no ROP pipeline: a bad request";
}

// ------------------------------------------------------------ through main

size_t lines_of(const std::string& s) { return size_t(std::count(s.begin(), s.end(), '\n')); }

/// r is a one-line user error on stderr naming `names`.
void expect_user_error_line(const Ran& r, const std::string& what, const std::string& names) {
  EXPECT_EQ(r.status, 1) << what << ": expected exit status 1 (a user error)\nstderr: " << r.err;
  EXPECT_EQ(lines_of(r.err), 1u) << what << ": stderr must be one line: " << r.err;
  EXPECT_EQ(r.err.rfind("ropsim: error: ", 0), 0u) << what << ": not the user error form: " << r.err;
  EXPECT_NE(r.err.find(names), std::string::npos) << what << ": the message does not name " << names << ": " << r.err;
}

TEST(Errors, BadInputsOfEveryKindExitWith1ThroughMain) {
  Scratch s("ropsim-test-errors");
  s.put("bad.rtr", "not a trace at all, just text\n");
  expect_user_error_line(ropsim_test::ropsim(s.dir, "run --trace bad.rtr --quiet"), "a bad trace (TraceError)",
                         "bad.rtr");
  s.put("bad-hw.toml", "[cache]\nno_such_key = 1\n");
  const Ran cfg = ropsim_test::ropsim(s.dir, "config bad-hw.toml");
  expect_user_error_line(cfg, "a bad config key (ConfigError)", "bad-hw.toml");
  EXPECT_NE(cfg.err.find("no_such_key"), std::string::npos) << "the config error does not name the key: " << cfg.err;
  expect_user_error_line(ropsim_test::ropsim(s.dir, "scene no-such-scene -o x.rtr"), "a bad scene (SceneError)",
                         "no-such-scene");
  s.put("bad-scene.toml", "width = 16\nheight = 16\nspp = 4\nno_such_key = 1\n");
  expect_user_error_line(ropsim_test::ropsim(s.dir, "capture bad-scene.toml -o x.rtr"),
                         "a bad capture scene file (CaptureError)", "bad-scene.toml");
  s.put("bad.png", "not a PNG\n");
  expect_user_error_line(ropsim_test::ropsim(s.dir, "compare bad.png bad.png"), "a bad image (ImageError)", "bad.png");
  EXPECT_FALSE(fs::exists(s.dir / "x.rtr")) << "a failed run left its output";
}

TEST(Errors, TheTestHookGivesExitStatus2ThroughMain) {
  Scratch s("ropsim-test-errors");
  const Ran r = ropsim_test::shell(s.dir, "env ROPSIM_TEST_INTERNAL_ERROR=1 '" ROPSIM_BINARY "' config");
  EXPECT_EQ(r.status, 2) << "the internal error hook did not give exit status 2: " << r.err;
  EXPECT_EQ(lines_of(r.err), 1u) << "stderr must be one line: " << r.err;
  EXPECT_EQ(r.err.rfind("ropsim: internal error: ", 0), 0u) << "not the internal error form: " << r.err;
  EXPECT_NE(r.err.find("please report it"), std::string::npos) << r.err;
}

// ------------------------------------------------------------ through workers

const char* kOnePointStudy = R"(
[inputs]
scenes = ["eight-layers"]

[axes]
spp = 4
width = 16
height = 16
)";

TEST(Errors, AStudyPointsUserErrorGivesExitStatus1) {
  Scratch s("ropsim-test-errors");
  // 3 ways: 65536 / (64 x 3) sets is no power of two, found when the point runs.
  s.put("ways.toml", std::string(kOnePointStudy) + "fidelity = \"cycle\"\n\"cache.ways\" = 3\n");
  const Ran r = ropsim_test::ropsim(s.dir, "study run ways.toml --out st -j 2 --quiet");
  EXPECT_EQ(r.status, 1) << "a point's user error must give the study exit status 1\n" << r.out << r.err;
  EXPECT_NE(r.out.find("power-of-two number of sets"), std::string::npos)
      << "the summary does not carry the point's error:\n"
      << r.out;
  EXPECT_EQ(r.out.find("internal error"), std::string::npos) << "a user error was reported as internal:\n" << r.out;
}

TEST(Errors, AStudyPointsBrokenInvariantGivesExitStatus2) {
  Scratch s("ropsim-test-errors");
  s.put("one.toml", kOnePointStudy);
  const std::string hook = "env ROPSIM_TEST_INTERNAL_ERROR=study-point '" ROPSIM_BINARY "' ";
  const Ran r = ropsim_test::shell(s.dir, hook + "study run one.toml --out st -j 2 --quiet");
  EXPECT_EQ(r.status, 2) << "a point's broken invariant (in a worker process) must give the study exit status 2\n"
                         << r.out << r.err;
  EXPECT_NE(r.out.find("internal error: test hook ROPSIM_TEST_INTERNAL_ERROR=study-point is set: please report it"),
            std::string::npos)
      << "the summary does not say the point's internal error as main would:\n"
      << r.out;
  // Run again (the failure recorded): the study still says 2.
  const Ran again = ropsim_test::ropsim(s.dir, "study run one.toml --out st -j 2 --quiet");
  EXPECT_EQ(again.status, 2) << "a recorded broken invariant must keep the study's exit status 2\n" << again.out;
  // One task in this process, as another executor runs it.
  const Ran task = ropsim_test::shell(s.dir, hook + "study task one.toml --out st2 --kind p --index 0");
  EXPECT_EQ(task.status, 2) << "study task: a broken invariant must give exit status 2\n" << task.err;
  EXPECT_EQ(lines_of(task.err), 1u) << "study task: stderr must be one line: " << task.err;
  EXPECT_EQ(task.err.rfind("ropsim: internal error: study task p 0 failed: ", 0), 0u)
      << "study task: not the internal error form: " << task.err;
}

TEST(Errors, ASampledWorkersBrokenInvariantGivesExitStatus2) {
  Scratch s("ropsim-test-errors");
  const Ran lib = ropsim_test::ropsim(s.dir,
                                      "livepoints --scene eight-layers --spp 4 --width 16 --height 12 --sample-units 3 "
                                      "--sample-size 16 --sample-warmup 8 --sample-cooldown 8 --sample-warming 16 "
                                      "-o lib.rlp");
  ASSERT_EQ(lib.status, 0) << "could not record the live-point library: " << lib.err;
  const std::string run = "run --fidelity sampled --livepoints lib.rlp -j 2 --quiet --report r.json";
  const Ran ok = ropsim_test::ropsim(s.dir, run);
  ASSERT_EQ(ok.status, 0) << "the sampled run fails without the hook: " << ok.err;
  const Ran r = ropsim_test::shell(s.dir, "env ROPSIM_TEST_INTERNAL_ERROR=livepoint-worker '" ROPSIM_BINARY "' " + run);
  EXPECT_EQ(r.status, 2) << "a live-point worker's broken invariant must give exit status 2: " << r.err;
  EXPECT_EQ(lines_of(r.err), 1u) << "stderr must be one line: " << r.err;
  EXPECT_EQ(r.err,
            "ropsim: internal error: test hook ROPSIM_TEST_INTERNAL_ERROR=livepoint-worker is set: please "
            "report it\n")
      << "the worker's error does not reach the user as main says it";
}

}  // namespace
