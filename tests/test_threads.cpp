// The golden model on several host threads (golden_model.h StochasticModel):
// the screen's tiles dealt to lanes must give the state, the image and the
// counters of one thread, bit for bit, for every built-in scene, every method
// with a ROP pipeline and spp 1, 16 and 64.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "rtl_models/golden/golden_model.h"
#include "sim/fidelity/functional/driver.h"
#include "tests/compare_util.h"
#include "util/host_threads.h"

using namespace ropsim;

namespace {

struct ModelRun {
  std::unique_ptr<FunctionalModel> model;
  const StochasticModel& sm() const { return dynamic_cast<const StochasticModel&>(*model); }
};

/// Every pass of the method over the fragments: one thread through draw(),
/// or `threads` through draw_batch() in batches of `batch`, with work beside.
ModelRun run_model(const FragmentList& fl, Method m, int threads, size_t batch) {
  GoldenConfig cfg;
  cfg.method = m;
  ModelRun r{make_functional_model(fl.header, cfg, threads)};
  uint64_t beside_calls = 0;
  for (int pass = 0; pass < r.model->passes(); ++pass) {
    r.model->begin_pass(pass);
    if (threads == 1) {
      for (const Fragment& f : fl.fragments) r.model->draw(f);
      continue;
    }
    for (size_t i = 0; i < fl.fragments.size(); i += batch)
      r.model->draw_batch(fl.fragments.data() + i, std::min(batch, fl.fragments.size() - i), [&] { ++beside_calls; });
  }
  if (threads > 1) {
    EXPECT_EQ(beside_calls, uint64_t(r.model->passes()) * ((fl.fragments.size() + batch - 1) / batch))
        << "draw_batch must call beside() once per batch";
  }
  return r;
}

std::string counter_difference(const Counters& a, const Counters& b) {
  std::vector<uint64_t> va, vb;
  a.for_each([&](const char*, uint64_t v) { va.push_back(v); });
  b.for_each([&](const char*, uint64_t v) { vb.push_back(v); });
  std::string out;
  size_t i = 0;
  a.for_each([&](const char* name, uint64_t) {
    if (va[i] != vb[i]) out += std::string(name) + " " + std::to_string(va[i]) + " vs " + std::to_string(vb[i]) + "; ";
    ++i;
  });
  return out;
}

class GoldenThreads : public ::testing::TestWithParam<std::string> {};

TEST_P(GoldenThreads, OneTwoAndThreeThreadsGiveTheSameBits) {
  for (int spp : {1, 16, 64}) {
    InputSpec in;
    in.scene.name = GetParam();
    in.scene.spp = spp;
    const FragmentList fl = load_fragments(in);
    ASSERT_GT(fl.fragments.size(), 0u);
    for (const std::string& name : method_names()) {
      Method m;
      ASSERT_TRUE(parse_method(name, m));
      if (m == Method::kReference) continue;
      const std::string where = GetParam() + " " + name + " at " + std::to_string(spp) + " spp";
      const ModelRun one = run_model(fl, m, 1, 0);
      // 2 threads (8 lanes) in the driver's batch size; 3 threads (12 lanes)
      // in batches that do not divide the input.
      for (auto [threads, batch] : {std::pair<int, size_t>{2, 4096}, {3, 999}}) {
        const ModelRun many = run_model(fl, m, threads, batch);
        const std::string w = where + ", " + std::to_string(threads) + " threads";
        EXPECT_EQ(counter_difference(one.model->counters(), many.model->counters()), "") << w << ": counters";
        EXPECT_EQ(first_state_difference(one.sm().store(), many.sm().store()), "") << w << ": state";
        EXPECT_EQ(ropsim_test::first_image_difference(one.model->resolve(), many.model->resolve()), "")
            << w << ": image";
        EXPECT_EQ(one.model->state_bytes(), many.model->state_bytes()) << w << ": state bytes";
      }
    }
  }
}

std::vector<std::string> scene_names() {
  std::vector<std::string> v;
  for (const auto& s : scene_catalog()) v.push_back(s.name);
  return v;
}

INSTANTIATE_TEST_SUITE_P(AllScenes, GoldenThreads, ::testing::ValuesIn(scene_names()), [](const auto& info) {
  std::string n = info.param;
  for (char& c : n)
    if (c == '-') c = '_';
  return n;
});

// The driver's path: run_functional with the reference beside the model.
TEST(GoldenThreadsDriver, RunFunctionalWithTheReferenceIsTheSameOnEveryThreadCount) {
  InputSpec in;
  in.scene.name = "smoke";
  in.scene.spp = 16;
  GoldenConfig cfg;
  const FunctionalRun a = run_functional(in, cfg, true, 1), b = run_functional(in, cfg, true, 2);
  EXPECT_EQ(a.threads, 1);
  EXPECT_EQ(b.threads, 2);
  EXPECT_EQ(counter_difference(a.counters, b.counters), "");
  EXPECT_EQ(ropsim_test::first_image_difference(a.image, b.image), "") << "the image";
  ASSERT_TRUE(a.reference && b.reference);
  EXPECT_EQ(ropsim_test::first_image_difference(*a.reference, *b.reference), "") << "the reference";
  EXPECT_EQ(a.state_bytes, b.state_bytes);
}

TEST(HostThreads, DefaultIsTheAvailableCoresAndTheSettingHolds) {
  EXPECT_GE(available_cores(), 1);
  const int before = host_threads();
  set_host_threads(3);
  EXPECT_EQ(host_threads(), 3);
  set_host_threads(before);
  EXPECT_EQ(host_threads(), before);
}

}  // namespace
