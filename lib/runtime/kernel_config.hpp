// kernel_config.hpp — one typed kernel configuration: the file and entry, and every switch the
// kernels read as a #define; the preamble, the label and the program key are derived from it.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

// Every #define a kernel file reads (kernels/config.cl and the files' own #if lines). A switch
// that is not set is not defined, and the kernel's default applies (kernels/config.cl).
enum class Switch : int {
  model,              // IVR_MODEL: 0 absorption, 1 emission–absorption
  tf,                 // IVR_TF: TfKind
  scheme,             // IVR_SCHEME: Scheme
  f64,                // IVR_F64: `real` is double
  acc_f64,            // IVR_ACC_F64: reductions accumulate in double (array_ops.cl)
  early_termination,  // IVR_EARLY_TERMINATION
  empty_space,        // IVR_EMPTY_SPACE: skip empty bricks (kernels/empty_space.cl)
  brick_size,         // IVR_BRICK_SIZE: cells per brick edge
  lanes,              // IVR_LANES: tangent lanes (jacobian.cl)
  rays,               // IVR_RAYS: rays per work-item in vector lanes (kernels/rays.cl: 1, 8, 16)
  packet_primal,      // IVR_PACKET_PRIMAL: the render writes (C, T) for the adjoint
  tangent_tf,         // IVR_TANGENT_TF: some lane is a TF parameter
  tangent_camera,     // IVR_TANGENT_CAMERA
  tangent_voxel,      // IVR_TANGENT_VOXEL
  jacobian,           // IVR_JACOBIAN: the tangent kernel writes the Jacobian
  loss_gradient,      // IVR_LOSS_GRADIENT: the tangent kernel sums d loss / d parameter
  loss_l1,            // IVR_LOSS_L1: the loss is l1 (else mse)
  loss_dot,           // IVR_LOSS_DOT: the loss is sum(target * image): dL/dpixel = target
  grad_density,       // IVR_GRAD_DENSITY: the adjoint scatters d loss / d voxel
  grad_tf,            // IVR_GRAD_TF
  grad_camera,        // IVR_GRAD_CAMERA
  tf_rows,            // IVR_TF_ROWS: Gaussians the adjoint's per-ray TF cache holds (adjoint_tf.cl)
  deterministic,      // IVR_DETERMINISTIC: fixed-point density gradient
  primal_given,       // IVR_PRIMAL_GIVEN: the adjoint reads the packet render's (C, T)
  scatter_cache,      // IVR_SCATTER_CACHE: work-group cache in front of the global scatter
  private_sums,       // IVR_PRIVATE_SUMS: one-item groups summing into their own copies
  reduce_size,        // IVR_REDUCE_SIZE: work-group size of array_ops.cl's reductions
  float_atomics,      // IVR_FLOAT_ATOMICS: cl_ext_float_atomics adds
  ptx_atomics,        // IVR_PTX_ATOMICS: NVIDIA's red.global.add through inline PTX
  ray_list,           // IVR_RAY_LIST: the rays are a list, not cameras' pixels (geometry.cl)
  ray_gradient,       // IVR_RAY_GRADIENT: the tangent kernel writes each ray's d loss / d column
  count_
};
constexpr int kSwitches = int(Switch::count_);

struct KernelConfig {
  std::string file;   // kernels/<file>, e.g. "render.cl"
  std::string entry;  // the __kernel's name, e.g. "render"
  AtomicAdd atomics = AtomicAdd::compare_and_swap;  // set through with_atomics()
  bool atomics_chosen = false;                      // with_atomics() was called

  KernelConfig() { values_.fill(kUnset); }
  KernelConfig(std::string file_name, std::string entry_name) : KernelConfig() {
    file = std::move(file_name);
    entry = std::move(entry_name);
  }

  KernelConfig& set(Switch s, int value) {
    values_[std::size_t(s)] = value;
    return *this;
  }
  KernelConfig& set(Switch s, bool value) { return set(s, value ? 1 : 0); }
  bool has(Switch s) const { return values_[std::size_t(s)] != kUnset; }
  int value(Switch s) const { return values_[std::size_t(s)]; }

  KernelConfig& with_precision(Precision precision) { return set(Switch::f64, precision == Precision::f64); }
  // The global atomic add of kernels/atomics.cl: its switch and the OpenCL C version
  // cl_ext_float_atomics needs (options()).
  KernelConfig& with_atomics(AtomicAdd kind);
  KernelConfig with_entry(const std::string& other) const {  // another kernel of the program
    KernelConfig c = *this;
    c.entry = other;
    return c;
  }

  // Derived, from the normalised switches (normalised()):
  std::string preamble() const;  // "#define IVR_MODEL 1\n…"
  // "render.cl [model=emission_absorption tf=gaussian scheme=midpoint f64 ert=on]": names the
  // program in build errors and the variant in statistics.
  std::string label() const;
  std::string key() const;  // what identifies the program: the file and the preamble
  // -DIVR_COUNT_ARITHMETIC=… (and its build flag), -cl-std=… and $IVR_BUILD_OPTIONS
  std::string options(const DeviceInfo& info) const;

  // Equivalent configurations made equal, so that they share a program: a brick size without
  // empty-space skipping, and the adjoint's TF row count except for a few Gaussians (1, 2, 4
  // or 8 cache rows; more go straight to local memory, 0), are dropped or rounded; the
  // preamble also leaves out switches at the kernels' default of 0.
  KernelConfig normalised() const;

 private:
  static constexpr int kUnset = -1;
  std::array<int, kSwitches> values_{};
};

// The switches the kernels read as 0 where undefined, which a preamble therefore leaves out at 0
// (tests/runtime/kernel_config_test.cpp checks the kernels' #ifndef defaults against it).
std::vector<std::string> switches_off_by_default();

}  // namespace ivr
