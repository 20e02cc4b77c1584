// options_test.cpp — the C API's option structs: each table (lib/capi/options/*.def) names every
// field of its struct in ivr.h in order, the init functions give the core's defaults, a struct
// from an older caller (a smaller size) keeps the defaults beyond its end, and a struct never
// filled by its init function is refused by name.
#include "capi/options.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <regex>
#include <sstream>

#include "ivr/ivr.h"
#include "ivr/ivr_session.h"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// The field names of `typedef struct NAME { … } NAME;` in a public header, in order.
std::vector<std::string> header_fields(const std::string& header, const std::string& name) {
  std::ifstream in(std::string(IVR_KERNELS_DIR) + "/../include/ivr/" + header);
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  const std::size_t open = s.find("typedef struct " + name + " {");
  EXPECT_NE(open, std::string::npos) << name;
  const std::size_t close = s.find("} " + name + ";", open);
  std::string body = s.substr(open, close - open);
  body = std::regex_replace(body, std::regex(R"(/\*[^*]*\*+(?:[^/*][^*]*\*+)*/)"), "");
  std::vector<std::string> names;
  const std::regex field(R"(\n\s*[A-Za-z_][\w ]*[\s*]([A-Za-z_]\w*)\s*;)");
  for (std::sregex_iterator m(body.begin(), body.end(), field), end; m != end; ++m)
    names.push_back((*m)[1]);
  return names;
}

TEST(CApiOptions, EachTableNamesEveryFieldOfItsStructInOrder) {
  const std::pair<const char*, const char*> structs[] = {{"ivr.h", "ivr_tomo_options"},
                                                         {"ivr.h", "ivr_reconstruct_options"},
                                                         {"ivr.h", "ivr_viewpoint_options"},
                                                         {"ivr_session.h", "ivr_session_options"}};
  for (const auto& [header, name] : structs) {
    std::vector<std::string> table;
    std::size_t end = 0;
    capi::each_option_field(name, [&](const capi::OptionField& f) {
      table.push_back(f.name);
      EXPECT_GE(f.offset, end) << name << "." << f.name << " is out of order";
      end = f.offset + f.size;
    });
    EXPECT_EQ(table, header_fields(header, name)) << name;
    EXPECT_FALSE(table.empty());
  }
}

TEST(CApiOptions, InitGivesTheCoreDefaultsAndSize) {
  ivr_tomo_options t;
  std::memset(&t, 0xff, sizeof t);
  ASSERT_EQ(ivr_tomo_options_init(&t), IVR_OK);
  const TomoOptions core;
  EXPECT_EQ(t.size, sizeof t);
  EXPECT_EQ(t.iterations, core.iterations);
  EXPECT_EQ(t.tv_epsilon, core.tv_epsilon);
  EXPECT_EQ(t.relaxation, core.relaxation);
  EXPECT_EQ(t.solver, IVR_SOLVER_CGLS);
  ivr_reconstruct_options r;
  ASSERT_EQ(ivr_reconstruct_options_init(&r), IVR_OK);
  const ReconstructOptions rc;
  EXPECT_EQ(r.size, sizeof r);
  EXPECT_EQ(r.iterations, rc.iterations);
  EXPECT_EQ(r.step_every, rc.optimizer.step_every);
  EXPECT_EQ(r.tv_epsilon, rc.tv_epsilon);
  EXPECT_EQ(r.optimizer, IVR_OPTIMIZER_AUTO);  // rc.automatic_optimizer
  EXPECT_EQ(r.seed, rc.seed);
  ivr_session_options s;
  ASSERT_EQ(ivr_session_options_init(&s), IVR_OK);
  EXPECT_EQ(s.min_empty_fraction, SessionOptions{}.min_empty_fraction);
  EXPECT_EQ(s.empty_space, 0);
  // Every field goes to the core and back unchanged.
  r.iterations = 17;
  r.optimizer = IVR_OPTIMIZER_LBFGS;
  r.schedule = IVR_SCHEDULE_COSINE;
  r.init = IVR_INIT_ZEROS;
  r.mode = IVR_MODE_FORWARD;
  r.seed = 99;
  const ivr_reconstruct_options back = capi::c_options(capi::core_options(&r));
  EXPECT_EQ(std::memcmp(&back, &r, sizeof r), 0);
}

TEST(CApiOptions, AnOlderSmallerStructKeepsTheDefaultsBeyondItsEnd) {
  ivr_tomo_options t;
  ivr_tomo_options_init(&t);
  t.tv_epsilon = 0.5;
  t.relaxation = 1.5;
  t.size = offsetof(ivr_tomo_options, relaxation);  // a caller built before `relaxation`
  const TomoOptions core = capi::core_options(&t);
  EXPECT_EQ(core.tv_epsilon, 0.5);
  EXPECT_EQ(core.relaxation, TomoOptions{}.relaxation);
}

TEST(CApiOptions, AStructNotFilledByItsInitFunctionIsRefused) {
  ivr_context* ctx = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &ctx), IVR_OK);
  ivr_scene* scene = nullptr;
  ASSERT_EQ(ivr_scene_from_json(ctx,
                                R"({"volume": {"synthetic": "shepp_logan", "dims": [4, 4, 4]}, "model": "absorption",
                                    "cameras": [{"eye": [0, 0, 2], "target": [0, 0, 0],
                                    "up": [0, 1, 0], "fov_y": 40, "width": 2, "height": 2}]})",
                                nullptr, &scene),
            IVR_OK)
      << ivr_last_error();
  ivr_session_options o{};  // zeroed, not initialised: size 0
  o.precision = IVR_PRECISION_F32;
  ivr_session* session = nullptr;
  EXPECT_EQ(ivr_session_create(ctx, scene, &o, &session), IVR_ERROR_INVALID_ARGUMENT);
  const std::string message = ivr_context_last_error(ctx);
  EXPECT_NE(message.find("options.size is 0: fill the ivr_session_options with its init function"),
            std::string::npos)
      << message;
  EXPECT_EQ(session, nullptr);
  ivr_session_options_init(&o);
  o.empty_space = 3;
  EXPECT_EQ(ivr_session_create(ctx, scene, &o, &session), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(ivr_context_last_error(ctx)).find("options.empty_space 3 is unknown"),
            std::string::npos);
  ivr_scene_release(scene);
  ivr_context_release(ctx);
}

}  // namespace
}  // namespace ivr::test
