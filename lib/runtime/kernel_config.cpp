// kernel_config.cpp — the typed kernel configuration's preamble, label, key and normalisation.
#include "runtime/kernel_config.hpp"

#include <cstdlib>
#include <sstream>
#include <vector>

#include "runtime/device_params.hpp"
#include "scene/tf_kinds.hpp"

namespace ivr {
namespace {

// How a switch shows in a label: its value as "name=value", or words for its values.
enum class Shown { value, on_off, flag, words };

struct SwitchInfo {
  const char* macro;
  const char* name;  // in labels
  Shown shown;
  bool zero_is_default;  // the kernels read an undefined switch as 0 (tests/runtime checks it)
};

// In the order of enum class Switch.
constexpr SwitchInfo kInfo[kSwitches] = {
    {"IVR_MODEL", "model", Shown::words, false},
    {"IVR_TF", "tf", Shown::words, false},
    {"IVR_SCHEME", "scheme", Shown::words, false},
    {"IVR_F64", "", Shown::words, false},
    {"IVR_ACC_F64", "acc", Shown::words, false},
    {"IVR_EARLY_TERMINATION", "ert", Shown::on_off, false},
    {"IVR_EMPTY_SPACE", "empty_space", Shown::on_off, true},
    {"IVR_BRICK_SIZE", "brick", Shown::value, false},
    {"IVR_LANES", "lanes", Shown::value, false},
    {"IVR_RAYS", "packet", Shown::value, false},
    {"IVR_PACKET_PRIMAL", "primal", Shown::flag, true},
    {"IVR_TANGENT_TF", "tangent_tf", Shown::flag, false},
    {"IVR_TANGENT_CAMERA", "tangent_camera", Shown::flag, false},
    {"IVR_TANGENT_VOXEL", "tangent_voxel", Shown::flag, false},
    {"IVR_JACOBIAN", "jacobian", Shown::flag, false},
    {"IVR_LOSS_GRADIENT", "loss_gradient", Shown::flag, false},
    {"IVR_LOSS_L1", "l1", Shown::flag, true},
    {"IVR_LOSS_DOT", "dot", Shown::flag, true},
    {"IVR_GRAD_DENSITY", "grad_density", Shown::flag, false},
    {"IVR_GRAD_TF", "grad_tf", Shown::flag, true},
    {"IVR_GRAD_CAMERA", "grad_camera", Shown::flag, true},
    {"IVR_TF_ROWS", "tf_rows", Shown::value, false},
    {"IVR_DETERMINISTIC", "deterministic", Shown::flag, true},
    {"IVR_PRIMAL_GIVEN", "primal_given", Shown::flag, true},
    {"IVR_SCATTER_CACHE", "scatter_cache", Shown::flag, true},
    {"IVR_PRIVATE_SUMS", "private_sums", Shown::flag, true},
    {"IVR_REDUCE_SIZE", "reduce", Shown::value, false},
    {"IVR_FLOAT_ATOMICS", "", Shown::flag, true},  // shown as atomics=… from KernelConfig::atomics
    {"IVR_PTX_ATOMICS", "", Shown::flag, true},
    {"IVR_RAY_LIST", "ray_list", Shown::flag, true},
    {"IVR_RAY_GRADIENT", "ray_gradient", Shown::flag, true},
};

std::string words(Switch s, int v) {
  switch (s) {
    case Switch::model:
      return std::string("model=") + (v == 0 ? "absorption" : "emission_absorption");
    case Switch::tf:
      return std::string("tf=") + tf_kind_name(TfKind(v));
    case Switch::scheme:
      return std::string("scheme=") + scheme_name(Scheme(v));
    case Switch::f64:
      return v ? "f64" : "f32";
    case Switch::acc_f64:
      return v ? "acc=f64" : "acc=f32";
    default:
      return std::to_string(v);
  }
}

}  // namespace

std::vector<std::string> switches_off_by_default() {
  std::vector<std::string> out;
  for (const SwitchInfo& info : kInfo)
    if (info.zero_is_default) out.push_back(info.macro);
  return out;
}

KernelConfig& KernelConfig::with_atomics(AtomicAdd kind) {
  atomics = kind;
  atomics_chosen = true;
  set(Switch::float_atomics, kind == AtomicAdd::ext_float_atomics);
  set(Switch::ptx_atomics, kind == AtomicAdd::ptx);
  return *this;
}

KernelConfig KernelConfig::normalised() const {
  KernelConfig c = *this;
  // The brick size is read only where bricks are skipped (or built: empty_space.cl sets no
  // IVR_EMPTY_SPACE and keeps it).
  if (c.has(Switch::empty_space) && c.value(Switch::empty_space) == 0)
    c.values_[std::size_t(Switch::brick_size)] = kUnset;
  // The adjoint's per-ray TF cache holds every Gaussian where there are at most 8, and none for
  // the other TF kinds (kernels/adjoint_tf.cl): the row count rounds up to 1, 2, 4 or 8 (the
  // slots beyond the TF's rows stay 0 and are never flushed), else 0, and is dropped for the other
  // kinds, so that a TF's size does not make a program of its own.
  if (c.has(Switch::tf_rows)) {
    const int rows = c.value(Switch::tf_rows);
    if (!c.has(Switch::tf) || TfKind(c.value(Switch::tf)) != TfKind::gaussian)
      c.values_[std::size_t(Switch::tf_rows)] = kUnset;
    else
      c.values_[std::size_t(Switch::tf_rows)] =
          rows > 8 ? 0 : rows > 4 ? 8 : rows > 2 ? 4 : rows > 1 ? 2 : 1;
  }
  return c;
}

std::string KernelConfig::preamble() const {
  const KernelConfig c = normalised();
  std::string out;
  for (int i = 0; i < kSwitches; ++i)  // a switch at the kernels' default of 0 is left out
    if (c.values_[std::size_t(i)] != kUnset &&
        !(kInfo[i].zero_is_default && c.values_[std::size_t(i)] == 0))
      out += std::string("#define ") + kInfo[i].macro + " " +
             std::to_string(c.values_[std::size_t(i)]) + "\n";
  return out;
}

std::string KernelConfig::label() const {
  const KernelConfig c = normalised();
  std::ostringstream out;
  out << file << " [";
  const char* space = "";
  for (int i = 0; i < kSwitches; ++i) {
    const int v = c.values_[std::size_t(i)];
    if (v == kUnset || (kInfo[i].shown == Shown::flag && (v == 0 || !*kInfo[i].name))) continue;
    out << space;
    space = " ";
    switch (kInfo[i].shown) {
      case Shown::value:
        out << kInfo[i].name << "=" << v;
        break;
      case Shown::on_off:
        out << kInfo[i].name << "=" << (v ? "on" : "off");
        break;
      case Shown::flag:
        out << kInfo[i].name;
        break;
      case Shown::words:
        out << words(Switch(i), v);
        break;
    }
  }
  if (atomics_chosen) out << space << "atomics=" << atomic_add_name(atomics);
  out << "]";
  return out.str();
}

std::string KernelConfig::key() const { return file + '\n' + preamble(); }

std::string KernelConfig::options(const DeviceInfo& info) const {
  const CountArithmetic count = count_arithmetic(info);
  std::string options = "-DIVR_COUNT_ARITHMETIC=" + std::to_string(int(count));
  if (count == CountArithmetic::option) options += " -cl-fp32-correctly-rounded-divide-sqrt";
  if (atomics == AtomicAdd::ext_float_atomics) options += " -cl-std=" + info.atomics_std;
  const char* extra = std::getenv("IVR_BUILD_OPTIONS");
  return extra && *extra ? options + " " + extra : options;
}

}  // namespace ivr
