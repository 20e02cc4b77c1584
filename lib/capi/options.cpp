// options.cpp — the C API's option structs ↔ the core's, generated field by field from the tables
// of lib/capi/options/*.def: one line per option, so that an option is declared in the C header,
// the core struct and its table, and converted nowhere else.
#include "capi/options.hpp"

#include <cstddef>
#include <string>

#include "capi/c_api_handles.hpp"

namespace ivr::capi {
namespace {

// --- codecs: how a C field and a core member convert ----------------------------------------------

struct Plain {
  template <class O, class M>
  static M to_c(const O&, const M& m) { return m; }
  template <class O, class M, class V>
  static void to_core(O&, M& m, V v, const char*) { m = v; }
};

struct Flag {
  template <class O>
  static int to_c(const O&, bool m) { return m ? 1 : 0; }
  template <class O>
  static void to_core(O&, bool& m, int v, const char*) { m = v != 0; }
};

template <class CEnum, class CoreEnum>
struct EnumValue {
  CEnum c;
  CoreEnum core;
  const char* name;
};

// An enum's values in both forms; the first is the one a core value maps to by default.
template <class CEnum, class CoreEnum, std::size_t N>
struct EnumCodec {
  const EnumValue<CEnum, CoreEnum> (&values)[N];

  CoreEnum core(CEnum v, const char* field) const {
    for (const auto& e : values)
      if (e.c == v) return e.core;
    std::string names;
    for (const auto& e : values) names += std::string(names.empty() ? "" : ", ") + e.name;
    throw CError{IVR_ERROR_INVALID_ARGUMENT, std::string("options.") + field + " " +
                                                 std::to_string(int(v)) + " is unknown (" +
                                                 names + ")"};
  }
  CEnum c(CoreEnum v) const {
    for (const auto& e : values)
      if (e.core == v) return e.c;
    return values[0].c;
  }
};
template <class CEnum, class CoreEnum, std::size_t N>
EnumCodec<CEnum, CoreEnum, N> codec(const EnumValue<CEnum, CoreEnum> (&values)[N]) {
  return {values};
}

constexpr EnumValue<ivr_precision, Precision> kPrecision[] = {
    {IVR_PRECISION_F32, Precision::f32, "IVR_PRECISION_F32"},
    {IVR_PRECISION_F64, Precision::f64, "IVR_PRECISION_F64"}};
constexpr EnumValue<ivr_solver, Solver> kSolver[] = {{IVR_SOLVER_CGLS, Solver::cgls, "IVR_SOLVER_CGLS"},
                                                     {IVR_SOLVER_SIRT, Solver::sirt, "IVR_SOLVER_SIRT"},
                                                     {IVR_SOLVER_LSQR, Solver::lsqr, "IVR_SOLVER_LSQR"}};
constexpr EnumValue<ivr_schedule, Schedule> kSchedule[] = {
    {IVR_SCHEDULE_CONSTANT, Schedule::constant, "IVR_SCHEDULE_CONSTANT"},
    {IVR_SCHEDULE_STEP, Schedule::step, "IVR_SCHEDULE_STEP"},
    {IVR_SCHEDULE_COSINE, Schedule::cosine, "IVR_SCHEDULE_COSINE"}};
constexpr EnumValue<ivr_loss, Loss> kLoss[] = {{IVR_LOSS_MSE, Loss::mse, "IVR_LOSS_MSE"},
                                               {IVR_LOSS_L1, Loss::l1, "IVR_LOSS_L1"},
                                               {IVR_LOSS_DOT, Loss::dot, "IVR_LOSS_DOT"}};
constexpr EnumValue<ivr_init, Init> kInit[] = {{IVR_INIT_SCENE, Init::scene, "IVR_INIT_SCENE"},
                                               {IVR_INIT_ZEROS, Init::zeros, "IVR_INIT_ZEROS"},
                                               {IVR_INIT_CONSTANT, Init::constant, "IVR_INIT_CONSTANT"}};
constexpr EnumValue<ivr_mode, Mode> kMode[] = {{IVR_MODE_AUTO, Mode::automatic, "IVR_MODE_AUTO"},
                                               {IVR_MODE_FORWARD, Mode::forward, "IVR_MODE_FORWARD"},
                                               {IVR_MODE_ADJOINT, Mode::adjoint, "IVR_MODE_ADJOINT"}};
// IVR_OPTIMIZER_AUTO is adam unless the option set says otherwise (AutomaticOptimizerCodec).
constexpr EnumValue<ivr_optimizer, OptimizerKind> kOptimizer[] = {
    {IVR_OPTIMIZER_AUTO, OptimizerKind::adam, "IVR_OPTIMIZER_AUTO"},
    {IVR_OPTIMIZER_ADAM, OptimizerKind::adam, "IVR_OPTIMIZER_ADAM"},
    {IVR_OPTIMIZER_SGD, OptimizerKind::sgd, "IVR_OPTIMIZER_SGD"},
    {IVR_OPTIMIZER_LBFGS, OptimizerKind::lbfgs, "IVR_OPTIMIZER_LBFGS"}};
// ivr_session_options.empty_space is an int: 0 automatic, 1 on, 2 off.
constexpr EnumValue<int, EmptySpace> kEmptySpace[] = {{0, EmptySpace::automatic, "0: automatic"},
                                                      {1, EmptySpace::on, "1: on"},
                                                      {2, EmptySpace::off, "2: off"}};

// An enum field converted through its table.
template <const auto& kTable>
struct TableCodec {
  template <class O, class M>
  static auto to_c(const O&, M m) { return codec(kTable).c(m); }
  template <class O, class M, class V>
  static void to_core(O&, M& m, V v, const char* field) { m = codec(kTable).core(v, field); }
};
using PrecisionCodec = TableCodec<kPrecision>;
using SolverCodec = TableCodec<kSolver>;
using ScheduleCodec = TableCodec<kSchedule>;
using LossCodec = TableCodec<kLoss>;
using InitCodec = TableCodec<kInit>;
using ModeCodec = TableCodec<kMode>;
using EmptySpaceCodec = TableCodec<kEmptySpace>;
using AdamIsAutomaticCodec = TableCodec<kOptimizer>;  // adam shows as IVR_OPTIMIZER_AUTO

// A reconstruction's automatic optimiser: adam, or lbfgs where only the TF is optimised.
struct AutomaticOptimizerCodec {
  static ivr_optimizer to_c(const ReconstructOptions& o, OptimizerKind m) {
    return o.automatic_optimizer ? IVR_OPTIMIZER_AUTO : codec(kOptimizer).c(m);
  }
  static void to_core(ReconstructOptions& o, OptimizerKind& m, ivr_optimizer v, const char* f) {
    m = codec(kOptimizer).core(v, f);
    o.automatic_optimizer = v == IVR_OPTIMIZER_AUTO;
  }
};

// --- the tables -------------------------------------------------------------------------------------

template <class C>
struct OptionSet;

// One field: its name, place in the C struct, and accessors of both sides.
#define IVR_OPTION(field, Codec, member)                                               \
  f(#field, offsetof(C, field), sizeof(C::field), [](auto& c) -> auto& { return c.field; }, \
    [](auto& o) -> auto& { return o.member; }, Codec{});
#define IVR_OPTION_SET_BEGIN(CStruct, CoreStruct) \
  template <>                                     \
  struct OptionSet<CStruct> {                     \
    using C = CStruct;                            \
    using Core = CoreStruct;                      \
    static constexpr const char* name = #CStruct; \
    template <class F>                            \
    static void each(F&& f) {
#define IVR_OPTION_SET_END \
  }                        \
  }                        \
  ;

IVR_OPTION_SET_BEGIN(ivr_tomo_options, TomoOptions)
#include "capi/options/tomo_options.def"
IVR_OPTION_SET_END
IVR_OPTION_SET_BEGIN(ivr_reconstruct_options, ReconstructOptions)
#include "capi/options/reconstruct_options.def"
IVR_OPTION_SET_END
IVR_OPTION_SET_BEGIN(ivr_viewpoint_options, ViewpointOptions)
#include "capi/options/viewpoint_options.def"
IVR_OPTION_SET_END
IVR_OPTION_SET_BEGIN(ivr_session_options, SessionOptions)
#include "capi/options/session_options.def"
IVR_OPTION_SET_END
#undef IVR_OPTION_SET_BEGIN
#undef IVR_OPTION_SET_END
#undef IVR_OPTION

template <class C>
C to_c(const typename OptionSet<C>::Core& o) {
  C c{};
  c.size = sizeof(C);
  OptionSet<C>::each([&](const char*, std::size_t, std::size_t, auto field, auto member, auto codec) {
    field(c) = decltype(codec)::to_c(o, member(o));
  });
  return c;
}

template <class C>
typename OptionSet<C>::Core to_core(const C* c) {
  typename OptionSet<C>::Core o;
  if (!c) return o;
  // The smallest struct a caller can have filled by its init function: the size and a field.
  if (c->size <= sizeof(c->size))
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 std::string("options.size is ") + std::to_string(c->size) + ": fill the " +
                     OptionSet<C>::name + " with its init function first"};
  OptionSet<C>::each([&](const char* name, std::size_t offset, std::size_t size, auto field,
                         auto member, auto codec) {
    if (offset + size <= c->size) decltype(codec)::to_core(o, member(o), field(*c), name);
  });
  return o;
}

template <class C>
void fields_of(const std::function<void(const OptionField&)>& f) {
  f({"size", offsetof(C, size), sizeof(std::size_t)});
  OptionSet<C>::each([&](const char* name, std::size_t offset, std::size_t size, auto, auto, auto) {
    f({name, offset, size});
  });
}

}  // namespace

ivr_tomo_options c_options(const TomoOptions& o) { return to_c<ivr_tomo_options>(o); }
ivr_reconstruct_options c_options(const ReconstructOptions& o) {
  return to_c<ivr_reconstruct_options>(o);
}
ivr_viewpoint_options c_options(const ViewpointOptions& o) { return to_c<ivr_viewpoint_options>(o); }
ivr_session_options c_options(const SessionOptions& o) { return to_c<ivr_session_options>(o); }

TomoOptions core_options(const ivr_tomo_options* c) { return to_core(c); }
ReconstructOptions core_options(const ivr_reconstruct_options* c) { return to_core(c); }
ViewpointOptions core_options(const ivr_viewpoint_options* c) { return to_core(c); }
SessionOptions core_options(const ivr_session_options* c) { return to_core(c); }

void each_option_field(const char* c_struct, const std::function<void(const OptionField&)>& f) {
  const std::string name = c_struct;
  if (name == "ivr_tomo_options") return fields_of<ivr_tomo_options>(f);
  if (name == "ivr_reconstruct_options") return fields_of<ivr_reconstruct_options>(f);
  if (name == "ivr_viewpoint_options") return fields_of<ivr_viewpoint_options>(f);
  if (name == "ivr_session_options") return fields_of<ivr_session_options>(f);
  throw CError{IVR_ERROR_INVALID_ARGUMENT, "no option table for '" + name + "'"};
}

}  // namespace ivr::capi
