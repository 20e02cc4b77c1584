// fuzz_checkpoint.cpp — a reconstruction checkpoint's JSON through read_checkpoint, as a run of
// 10 iterations on two levels (3 then 24 voxels, Adam) with 4 TF parameters (Adam and L-BFGS
// state both) expects it; beside it lie float64 arrays of 3 and 24 values (d3.npy, d24.npy) and
// a float32 one (f24.npy) for it to name.
#include <vector>

#include "fuzz_support.hpp"
#include "ivr/volume_io.hpp"
#include "reconstruct/reconstruct_checkpoint.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const ivr::CheckpointShape shape = [] {
    const std::vector<double> d24(24, 0.25);
    const std::vector<float> f24(24, 0.5f);
    ivr::save_npy(ivr::fuzz::scratch() + "/d3.npy", {3}, d24.data());
    ivr::save_npy(ivr::fuzz::scratch() + "/d24.npy", {2, 3, 4}, d24.data());
    ivr::save_npy(ivr::fuzz::scratch() + "/f24.npy", {24}, f24.data());
    ivr::CheckpointShape s;
    s.fingerprint = {{"grid", {4, 3, 2}}, {"optimizer", "adam"}};
    s.iterations = 10;
    s.level_of = [](int i) { return i < 5 ? 0 : 1; };
    s.voxels = {3, 24};
    s.density_second_moments = true;
    s.tf_parameters = 4;
    s.tf_optimizer_second_moments = true;
    s.lbfgs_history = 3;
    return s;
  }();
  ivr::fuzz::put("run_checkpoint.json", data, size);
  ivr::fuzz::clean([&] { ivr::read_checkpoint(ivr::fuzz::scratch() + "/run", shape); });
  return 0;
}
