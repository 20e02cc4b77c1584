// runtime.cpp — OpenCL platform/device discovery, selection by index/type/name/$IVR_DEVICE,
// context and queue creation, and readable OpenCL errors.
#include "runtime/runtime.hpp"

#include "runtime/device_memory.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <sstream>
#include <thread>

namespace ivr {

const char* cl_error_name(int code) {
  switch (code) {
#define IVR_CL_CASE(name) \
  case name:              \
    return #name;
    IVR_CL_CASE(CL_SUCCESS)
    IVR_CL_CASE(CL_DEVICE_NOT_FOUND)
    IVR_CL_CASE(CL_DEVICE_NOT_AVAILABLE)
    IVR_CL_CASE(CL_COMPILER_NOT_AVAILABLE)
    IVR_CL_CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    IVR_CL_CASE(CL_OUT_OF_RESOURCES)
    IVR_CL_CASE(CL_OUT_OF_HOST_MEMORY)
    IVR_CL_CASE(CL_PROFILING_INFO_NOT_AVAILABLE)
    IVR_CL_CASE(CL_MEM_COPY_OVERLAP)
    IVR_CL_CASE(CL_IMAGE_FORMAT_MISMATCH)
    IVR_CL_CASE(CL_IMAGE_FORMAT_NOT_SUPPORTED)
    IVR_CL_CASE(CL_BUILD_PROGRAM_FAILURE)
    IVR_CL_CASE(CL_MAP_FAILURE)
    IVR_CL_CASE(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    IVR_CL_CASE(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    IVR_CL_CASE(CL_COMPILE_PROGRAM_FAILURE)
    IVR_CL_CASE(CL_LINKER_NOT_AVAILABLE)
    IVR_CL_CASE(CL_LINK_PROGRAM_FAILURE)
    IVR_CL_CASE(CL_DEVICE_PARTITION_FAILED)
    IVR_CL_CASE(CL_KERNEL_ARG_INFO_NOT_AVAILABLE)
    IVR_CL_CASE(CL_INVALID_VALUE)
    IVR_CL_CASE(CL_INVALID_DEVICE_TYPE)
    IVR_CL_CASE(CL_INVALID_PLATFORM)
    IVR_CL_CASE(CL_INVALID_DEVICE)
    IVR_CL_CASE(CL_INVALID_CONTEXT)
    IVR_CL_CASE(CL_INVALID_QUEUE_PROPERTIES)
    IVR_CL_CASE(CL_INVALID_COMMAND_QUEUE)
    IVR_CL_CASE(CL_INVALID_HOST_PTR)
    IVR_CL_CASE(CL_INVALID_MEM_OBJECT)
    IVR_CL_CASE(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR)
    IVR_CL_CASE(CL_INVALID_IMAGE_SIZE)
    IVR_CL_CASE(CL_INVALID_SAMPLER)
    IVR_CL_CASE(CL_INVALID_BINARY)
    IVR_CL_CASE(CL_INVALID_BUILD_OPTIONS)
    IVR_CL_CASE(CL_INVALID_PROGRAM)
    IVR_CL_CASE(CL_INVALID_PROGRAM_EXECUTABLE)
    IVR_CL_CASE(CL_INVALID_KERNEL_NAME)
    IVR_CL_CASE(CL_INVALID_KERNEL_DEFINITION)
    IVR_CL_CASE(CL_INVALID_KERNEL)
    IVR_CL_CASE(CL_INVALID_ARG_INDEX)
    IVR_CL_CASE(CL_INVALID_ARG_VALUE)
    IVR_CL_CASE(CL_INVALID_ARG_SIZE)
    IVR_CL_CASE(CL_INVALID_KERNEL_ARGS)
    IVR_CL_CASE(CL_INVALID_WORK_DIMENSION)
    IVR_CL_CASE(CL_INVALID_WORK_GROUP_SIZE)
    IVR_CL_CASE(CL_INVALID_WORK_ITEM_SIZE)
    IVR_CL_CASE(CL_INVALID_GLOBAL_OFFSET)
    IVR_CL_CASE(CL_INVALID_EVENT_WAIT_LIST)
    IVR_CL_CASE(CL_INVALID_EVENT)
    IVR_CL_CASE(CL_INVALID_OPERATION)
    IVR_CL_CASE(CL_INVALID_GL_OBJECT)
    IVR_CL_CASE(CL_INVALID_BUFFER_SIZE)
    IVR_CL_CASE(CL_INVALID_MIP_LEVEL)
    IVR_CL_CASE(CL_INVALID_GLOBAL_WORK_SIZE)
    IVR_CL_CASE(CL_INVALID_PROPERTY)
    IVR_CL_CASE(CL_INVALID_IMAGE_DESCRIPTOR)
    IVR_CL_CASE(CL_INVALID_COMPILER_OPTIONS)
    IVR_CL_CASE(CL_INVALID_LINKER_OPTIONS)
    IVR_CL_CASE(CL_INVALID_DEVICE_PARTITION_COUNT)
#undef IVR_CL_CASE
    case -1001:
      return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
      return "CL_UNKNOWN_ERROR";
  }
}

[[noreturn]] void throw_cl(const cl::Error& e, const std::string& doing) {
  const int code = e.err();
  Status status = Status::opencl;
  if (code == CL_MEM_OBJECT_ALLOCATION_FAILURE || code == CL_OUT_OF_RESOURCES ||
      code == CL_OUT_OF_HOST_MEMORY || code == CL_INVALID_BUFFER_SIZE)
    status = Status::out_of_memory;
  if (code == -1001 || code == CL_DEVICE_NOT_FOUND) status = Status::no_device;
  std::ostringstream msg;
  msg << e.what() << " failed with " << cl_error_name(code) << " (" << code << ") while " << doing;
  throw Error(status, msg.str(), code);
}

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(std::string s) {
  while (!s.empty() && (std::isspace((unsigned char)s.back()) || s.back() == '\0')) s.pop_back();
  std::size_t i = 0;
  while (i < s.size() && std::isspace((unsigned char)s[i])) ++i;
  return s.substr(i);
}

// cl_ext_float_atomics (values from the Khronos registry; older headers lack them).
constexpr cl_device_info kSingleFpAtomicCaps = 0x4231, kDoubleFpAtomicCaps = 0x4232;
constexpr cl_bitfield kGlobalFpAtomicAdd = 1 << 1, kLocalFpAtomicAdd = 1 << 17;

// Which float atomic adds the device has, and the OpenCL C version (2.0 or later) that has the
// atomic types they need.
void query_float_atomics(const cl::Device& dev, DeviceInfo& info) {
  if (dev.getInfo<CL_DEVICE_EXTENSIONS>().find("cl_ext_float_atomics") == std::string::npos) return;
  const auto has_add = [&](cl_device_info what) {
    cl_bitfield caps = 0;
    if (clGetDeviceInfo(dev(), what, sizeof caps, &caps, nullptr) != CL_SUCCESS) return false;
    const cl_bitfield both = kGlobalFpAtomicAdd | kLocalFpAtomicAdd;
    return (caps & both) == both;
  };
  // "OpenCL 3.0 …" devices compile OpenCL C 3.0; "OpenCL 2.x" ones OpenCL C 2.0.
  if (info.version.rfind("OpenCL 3.", 0) == 0)
    info.atomics_std = "CL3.0";
  else if (info.version.rfind("OpenCL 2.", 0) == 0)
    info.atomics_std = "CL2.0";
  else
    return;
  info.float_atomic_add = has_add(kSingleFpAtomicCaps);
  info.double_atomic_add = info.fp64 && has_add(kDoubleFpAtomicCaps);
}

// NVIDIA's compute capability, where its OpenCL reports it (cl_nv_device_attribute_query; the
// values are that extension's CL_DEVICE_COMPUTE_CAPABILITY_MAJOR_NV and _MINOR_NV).
int nv_compute_capability(const cl::Device& dev) {
  if (dev.getInfo<CL_DEVICE_EXTENSIONS>().find("cl_nv_device_attribute_query") ==
      std::string::npos)
    return 0;
  cl_uint major = 0, minor = 0;
  if (clGetDeviceInfo(dev(), 0x4000, sizeof major, &major, nullptr) != CL_SUCCESS ||
      clGetDeviceInfo(dev(), 0x4001, sizeof minor, &minor, nullptr) != CL_SUCCESS)
    return 0;
  return int(major * 10 + minor);
}

struct Found {
  DeviceInfo info;
  cl::Platform platform;
  cl::Device device;
};

std::vector<Found> discover() {
  // One thread at a time: the first listing initialises the platforms' drivers, and two threads
  // doing so at once (contexts made on several threads) made PoCL report no device to one.
  static std::mutex listing;
  std::lock_guard<std::mutex> lock(listing);
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error& e) {
    if (e.err() == -1001 || e.err() == CL_INVALID_VALUE)
      throw Error(Status::no_device,
                  "no OpenCL platform found (is an ICD such as pocl-opencl-icd installed?)");
    throw_cl(e, "listing OpenCL platforms");
  }
  if (platforms.empty())
    throw Error(Status::no_device,
                "no OpenCL platform found (is an ICD such as pocl-opencl-icd installed?)");
  std::vector<Found> found;
  for (std::size_t p = 0; p < platforms.size(); ++p) {
    std::vector<cl::Device> devices;
    try {
      platforms[p].getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      continue;  // a platform without devices is not an error
    }
    for (std::size_t d = 0; d < devices.size(); ++d) {
      const cl::Device& dev = devices[d];
      DeviceInfo info;
      info.index = int(found.size());
      info.platform_index = int(p);
      info.device_index = int(d);
      info.platform = trim(platforms[p].getInfo<CL_PLATFORM_NAME>());
      info.name = trim(dev.getInfo<CL_DEVICE_NAME>());
      info.vendor = trim(dev.getInfo<CL_DEVICE_VENDOR>());
      info.version = trim(dev.getInfo<CL_DEVICE_VERSION>());
      info.driver = trim(dev.getInfo<CL_DRIVER_VERSION>());
      const cl_device_type type = dev.getInfo<CL_DEVICE_TYPE>();
      info.type = (type & CL_DEVICE_TYPE_GPU)           ? "gpu"
                  : (type & CL_DEVICE_TYPE_CPU)         ? "cpu"
                  : (type & CL_DEVICE_TYPE_ACCELERATOR) ? "accelerator"
                                                        : "other";
      info.fp64 = dev.getInfo<CL_DEVICE_DOUBLE_FP_CONFIG>() != 0;
      info.correctly_rounded_divide_sqrt =
          (dev.getInfo<CL_DEVICE_SINGLE_FP_CONFIG>() & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) != 0;
      info.global_memory = dev.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
      info.max_allocation = dev.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
      info.compute_units = int(dev.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());
      info.max_clock_mhz = int(dev.getInfo<CL_DEVICE_MAX_CLOCK_FREQUENCY>());
      info.host_unified_memory = dev.getInfo<CL_DEVICE_HOST_UNIFIED_MEMORY>() != 0;
      query_float_atomics(dev, info);
      info.nv_compute_capability = nv_compute_capability(dev);
      found.push_back({info, platforms[p], dev});
    }
  }
  if (found.empty()) throw Error(Status::no_device, "no OpenCL device found on any platform");
  return found;
}

// A non-negative index written in decimal, or -1 if `s` is not one (or absurdly large).
int parse_index(const std::string& s) {
  if (s.empty() || s.size() > 6 ||
      !std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); }))
    return -1;
  return std::stoi(s);
}

const Found& select(const std::vector<Found>& all, const std::string& selector_in) {
  std::string selector = trim(selector_in);
  std::string origin = "device selector";
  if (selector.empty()) {
    const char* env = std::getenv("IVR_DEVICE");
    if (env && *env) {
      selector = trim(env);
      origin = "IVR_DEVICE";
    }
  }
  if (selector.empty()) {
    for (const Found& f : all)
      if (f.info.type == "gpu") return f;
    return all.front();
  }
  const std::string key = lower(selector);
  const std::size_t colon = key.find(':');
  const int index = parse_index(key);
  const int platform = colon == std::string::npos ? -1 : parse_index(key.substr(0, colon));
  const int device = colon == std::string::npos ? -1 : parse_index(key.substr(colon + 1));
  for (const Found& f : all) {
    if (index >= 0 && f.info.index == index) return f;
    if (platform >= 0 && device >= 0 && f.info.platform_index == platform &&
        f.info.device_index == device)
      return f;
    if (key == f.info.type) return f;
  }
  for (const Found& f : all)
    if (lower(f.info.platform + " " + f.info.name).find(key) != std::string::npos) return f;
  std::ostringstream msg;
  msg << "no OpenCL device matches " << origin << " '" << selector << "'; available:";
  for (const Found& f : all)
    msg << " [" << f.info.index << "] " << f.info.name << " (" << f.info.type << ", "
        << f.info.platform << ")";
  throw Error(Status::no_device, msg.str());
}

}  // namespace

std::vector<DeviceInfo> list_devices() {
  std::vector<DeviceInfo> out;
  for (const Found& f : discover()) out.push_back(f.info);
  return out;
}

Device::Device(const std::string& selector) : impl_(std::make_unique<Impl>()) {
  const std::vector<Found> all = discover();
  const Found& f = select(all, selector);
  impl_->info = f.info;
  impl_->platform = f.platform;
  impl_->device = f.device;
  cl_call("creating a context and queue on " + f.info.name, [&] {
    impl_->context = cl::Context(f.device);
    impl_->queue = cl::CommandQueue(impl_->context, f.device, CL_QUEUE_PROFILING_ENABLE);
  });
}

// Waits for the queue for the same reason as ~Session (lib/session/session_api.cpp): no launch may still
// be compiling in PoCL's worker threads when the process exits.
Device::~Device() {
  if (!impl_) return;
  try {
    impl_->queue.finish();
  } catch (...) {
  }
}
Device::Device(Device&&) noexcept = default;
Device& Device::operator=(Device&&) noexcept = default;
const DeviceInfo& Device::info() const {
  return impl_->info;
}

namespace {
std::atomic<long> allocation_countdown{0};  // inject_allocation_failure
}  // namespace

cl::Buffer Device::Impl::buffer(cl_mem_flags flags, std::size_t bytes, const void* host,
                                const char* what) {
  if (bytes > info.max_allocation) {
    std::ostringstream msg;
    msg << what << " needs " << bytes << " bytes, more than the " << info.max_allocation
        << "-byte largest allocation of " << info.name;
    throw Error(Status::out_of_memory, msg.str());
  }
  if (host && !(flags & CL_MEM_USE_HOST_PTR)) flags |= CL_MEM_COPY_HOST_PTR;
  const std::size_t size = std::max<std::size_t>(bytes, 1);
  // Over the cap, first let the driver count out what was just released (Live::settle).
  if (const std::uint64_t limit = device_memory_limit_from_env();
      limit && std::uint64_t(live->bytes.load()) + size > limit &&
      (size > limit || std::uint64_t(live->settle(std::int64_t(limit - size))) + size > limit)) {
    std::ostringstream msg;
    msg << what << " needs " << size << " bytes, which would take the device memory in use to "
        << live->bytes.load() + std::int64_t(size) << " bytes, over IVR_DEVICE_MEMORY_LIMIT ("
        << limit << " bytes; out-of-core bricks: docs/scaling.md)";
    throw Error(Status::out_of_memory, msg.str());
  }
  if (allocation_countdown > 0 && allocation_countdown.fetch_sub(1) == 1)
    throw_cl(cl::Error(CL_MEM_OBJECT_ALLOCATION_FAILURE, "clCreateBuffer (injected)"),
             std::string("allocating ") + what);
  cl::Buffer b = cl_call(std::string("allocating ") + what, [&] {
    return cl::Buffer(context, flags, size, const_cast<void*>(host));
  });
  // Counted out by the driver when the last reference goes, whoever holds it.
  struct Tracker {
    std::shared_ptr<Live> live;
    std::int64_t bytes;
  };
  auto* tracker = new Tracker{live, std::int64_t(size)};
  const std::int64_t now = live->bytes += tracker->bytes;
  for (std::int64_t p = live->peak.load(); now > p && !live->peak.compare_exchange_weak(p, now);) {
  }
  live->buffers += 1;
  const cl_int status = clSetMemObjectDestructorCallback(
      b(),
      [](cl_mem, void* user) {
        const auto* t = static_cast<Tracker*>(user);
        t->live->bytes -= t->bytes;
        t->live->buffers -= 1;
        delete t;
      },
      tracker);
  if (status != CL_SUCCESS) {  // not counted then
    live->bytes -= tracker->bytes;
    live->buffers -= 1;
    delete tracker;
  }
  return b;
}

std::int64_t Device::Impl::Live::settle(std::int64_t target, int max_ms) const {
  std::int64_t last = bytes.load();
  for (int quiet = 0, waited = 0; last > target && quiet < 10 && waited < max_ms; ++waited) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const std::int64_t now = bytes.load();
    quiet = now < last ? 0 : quiet + 1;
    last = now;
  }
  return last;
}

void inject_allocation_failure(long nth) {
  allocation_countdown = nth;
}

namespace {

bool offers(const DeviceInfo& info, bool f64, AtomicAdd kind) {
  switch (kind) {
    case AtomicAdd::ext_float_atomics:
      return f64 ? info.double_atomic_add : info.float_atomic_add;
    case AtomicAdd::ptx:
      return info.nv_compute_capability >= (f64 ? 60 : 20);
    case AtomicAdd::compare_and_swap:
      break;
  }
  return true;
}

}  // namespace

const char* atomic_add_name(AtomicAdd kind) {
  switch (kind) {
    case AtomicAdd::ext_float_atomics:
      return "cl_ext_float_atomics";
    case AtomicAdd::ptx:
      return "ptx";
    case AtomicAdd::compare_and_swap:
      break;
  }
  return "compare-and-swap";
}

AtomicAdd atomic_add_for(const DeviceInfo& info, bool f64) {
  const char* env = std::getenv("IVR_ATOMICS");
  std::string forced = env ? env : "";
  if (forced.empty()) {  // the older switch: IVR_FLOAT_ATOMICS=0 asks for the loop
    const char* old = std::getenv("IVR_FLOAT_ATOMICS");
    if (old && std::string(old) == "0") forced = "cas";
  }
  if (forced.empty() || forced == "auto") {
    for (AtomicAdd kind : {AtomicAdd::ext_float_atomics, AtomicAdd::ptx})
      if (offers(info, f64, kind)) return kind;
    return AtomicAdd::compare_and_swap;
  }
  AtomicAdd kind;
  if (forced == "ext")
    kind = AtomicAdd::ext_float_atomics;
  else if (forced == "ptx")
    kind = AtomicAdd::ptx;
  else if (forced == "cas")
    kind = AtomicAdd::compare_and_swap;
  else
    throw Error(Status::invalid_argument,
                "IVR_ATOMICS must be auto, ext, ptx or cas, got '" + forced + "'");
  if (!offers(info, f64, kind))
    throw Error(Status::invalid_argument,
                "IVR_ATOMICS=" + forced + ": " + info.name + " has no " +
                    (kind == AtomicAdd::ptx
                         ? std::string("inline-PTX ") + (f64 ? "float64" : "float32") +
                               " atomic add (NVIDIA's OpenCL, compute capability " +
                               (f64 ? "6.0" : "2.0") + " or later)"
                         : std::string("cl_ext_float_atomics ") + (f64 ? "float64" : "float32") +
                               " atomic add"));
  return kind;
}

bool fp64_count_usable(const DeviceInfo& info) {
  return info.fp64 && info.platform.find("NVIDIA") == std::string::npos;
}

CountArithmetic count_arithmetic(const DeviceInfo& info) {
  const char* env = std::getenv("IVR_COUNT_ARITHMETIC");
  const std::string forced = env ? env : "";
  if (forced.empty() || forced == "auto")
    return fp64_count_usable(info) ? CountArithmetic::fp64 : CountArithmetic::residual;
  if (forced == "fp64" && fp64_count_usable(info)) return CountArithmetic::fp64;
  if (forced == "option" && info.correctly_rounded_divide_sqrt) return CountArithmetic::option;
  if (forced == "residual") return CountArithmetic::residual;
  if (forced == "fp64" || forced == "option")
    throw Error(Status::invalid_argument,
                "IVR_COUNT_ARITHMETIC=" + forced + ": " + info.name + " has no " +
                    (forced == "fp64" ? "float64 quotient its compiler keeps"
                                      : "correctly rounded float32 division"));
  throw Error(Status::invalid_argument, "IVR_COUNT_ARITHMETIC must be auto, fp64, option or "
                                        "residual, got '" + forced + "'");
}

}  // namespace ivr
