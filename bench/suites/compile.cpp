// compile.cpp — the compile suite: the time to build the kernels a render, a density gradient and
// a forward-mode gradient need, cold (an empty program cache) and from the disk caches (a fresh
// device handle, so the in-process programs are gone): ivr's, or on PoCL PoCL's own, which ivr
// relies on there (lib/runtime/program_cache.cpp). The render reports its build time
// itself; for the others it is the first call's time less the median of warm calls.
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <random>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../runner/suite.hpp"

namespace ivr::bench {

void compile_suite(Context& ctx) {
  const int n = ctx.quick ? 32 : 64, image = ctx.quick ? 32 : 64;
  const Scene scene = bench_scene(n, image);
  const Image target = perturbed_target(ctx.device, scene, 0.5);
  const std::string selector = std::to_string(ctx.device.info().index);
  const std::string cache = ctx.work_dir + "/kernel-cache-" + selector;
  std::filesystem::remove_all(cache);
  const ScopedEnv env("IVR_CACHE_DIR", cache);
  const std::vector<Parameter> lanes = parameters_of(scene, "tf");

  struct Operation {
    std::string name;
    std::function<double(Device&)> run;  // returns the build seconds it reports, or < 0
  };
  const std::vector<Operation> ops = {{"render",
                                       [&](Device& d) {
                                         RenderStats s;
                                         render(d, scene, {Precision::f32, 0.5}, &s);
                                         return s.build_seconds;
                                       }},
                                      {"gradient",
                                       [&](Device& d) {
                                         AdjointOptions o;
                                         o.step = 0.5;
                                         adjoint(d, scene, target, o);
                                         return -1.0;
                                       }},
                                      {"forward_16_lanes", [&](Device& d) {
                                         JacobianOptions o;
                                         o.step = 0.5;
                                         jacobian(d, scene, lanes, &target, o);
                                         return -1.0;
                                       }}};
  // A build option no earlier compile used makes the programs new to PoCL's kernel cache too (its
  // key includes the options), so "cold" is cold without disabling or clearing that cache.
  const std::string user_options =
      std::getenv("IVR_BUILD_OPTIONS") ? std::getenv("IVR_BUILD_OPTIONS") : "";
  std::random_device entropy;
  for (const Operation& op : ops) {
    Record r{ctx.device_key, "compile", op.name, "ivr", {{"volume", n}, {"image", image}}};
    const ScopedEnv salted("IVR_BUILD_OPTIONS", user_options + " -DIVR_COLD_COMPILE_SALT=" +
                                                    std::to_string(entropy()) +
                                                    std::to_string(entropy()));
    for (const char* phase : {"cold", "cached"}) {
      Device fresh(selector);
      double reported = -1;
      const double first = wall_seconds([&] { reported = op.run(fresh); });
      if (reported >= 0) {
        r.metrics[std::string("compile_") + phase + "_s"] = reported;
        r.params["method"] = "the build time the render reports";
      } else {
        std::vector<double> warm;
        for (int i = 0; i < 3; ++i) warm.push_back(wall_seconds([&] { op.run(fresh); }));
        r.metrics[std::string("compile_") + phase + "_s"] = std::max(0.0, first - median(warm));
        r.params["method"] = "first call less the median of 3 warm calls";
      }
      r.metrics[std::string("first_call_") + phase + "_s"] = first;
    }
    r.params["cold"] = "a fresh ivr program cache and a build option new to PoCL's cache";
    std::cerr << "ivr-bench: compile/" << op.name << ": cold " << r.metrics["compile_cold_s"]
              << " s, cached " << r.metrics["compile_cached_s"] << " s\n";
    ctx.results.add(std::move(r));
  }
}

}  // namespace ivr::bench
