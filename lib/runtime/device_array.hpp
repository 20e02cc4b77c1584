// device_array.hpp — internal: the device array's state, and the array kernels of
// kernels/array_ops.cl (conversions, reductions, gathers, column copies) that sessions run.
#pragma once
#include <CL/opencl.hpp>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "ivr/session.hpp"
#include "runtime/launch.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

// Host access to one buffer (DeviceArray::map, wrap), shared by its reshaped views: the mapping
// and its count, and for wrapped host memory the wait that keeps the caller's memory in use until
// no command reads it. Holds the buffer and queue so that its destructor can unmap and wait.
struct HostAccess {
  std::mutex mutex;
  cl::Buffer buffer;
  cl::CommandQueue queue;
  std::size_t bytes = 0;
  void* mapped = nullptr;
  int maps = 0;
  bool borrowed = false;  // the buffer is the caller's memory (CL_MEM_USE_HOST_PTR)
  ~HostAccess();
};

struct DeviceArray::Impl {
  const Device* device = nullptr;  // the owner (arrays of other devices are refused)
  Device::Impl* dev = nullptr;
  cl::Buffer buffer;
  std::vector<std::int64_t> shape;
  DType dtype = DType::f32;
  std::size_t size = 0;  // elements
  cl::Event written;     // the last command that writes it (null: none pending)
  std::shared_ptr<Impl> base;  // a reshaped view keeps the array it views alive (and busy)
  std::shared_ptr<HostAccess> host;  // map/unmap state, shared with the views
};

std::size_t dtype_size(DType dtype);
DType real_dtype(bool f64);

// A new array; `what` names it in allocation errors. Not initialised; or, with `host`, over that
// memory (CL_MEM_USE_HOST_PTR: DeviceArray::wrap).
DeviceArray make_array(const Device& device, Device::Impl& dev, std::vector<std::int64_t> shape,
                       DType dtype, const char* what, void* host = nullptr);
// The same buffer under another shape of the same size.
DeviceArray reshape(const DeviceArray& array, std::vector<std::int64_t> shape);
// "(4, 256, 256, 4)"
std::string shape_text(const std::vector<std::int64_t>& shape);
// The device buffer behind an array, and the event that last wrote it.
inline const cl::Buffer& buffer_of(const DeviceArray& a) {
  return a.impl()->buffer;
}
inline void mark_written(const DeviceArray& a, const cl::Event& e) {
  a.impl()->written = e;
}

// The kernels of kernels/array_ops.cl for arrays of one real type, on one owner's kernel set.
// Every call enqueues and returns the last event; nothing waits.
class ArrayKernels {
 public:
  ArrayKernels(Device::Impl& dev, KernelSet& kernels, bool f64);
  bool acc_f64() const { return acc_f64_; }  // sums are double (the device has float64)
  DType acc_dtype() const { return acc_f64_ ? DType::f64 : DType::f32; }

  // One pass over n reals (volume_check, per work-group, reduced here; waits): *lo, *hi their
  // range, the return value the first index holding one that is not finite — or negative,
  // unless allow_negative — else n.
  std::uint64_t check_values(const cl::Buffer& values, std::uint64_t n, bool allow_negative,
                             double* lo, double* hi, std::vector<cl::Event>& events);
  // out[b·cols + c] = Σ_r in[(b·rows + r)·cols + c] for b < blocks, accumulated as acc_dtype().
  cl::Event sum_rows(const cl::Buffer& in, int rows, int cols, int blocks, const cl::Buffer& out);
  // The loss of `image` (float32) against `target` (reals), n elements, into out[0]; `kind` is
  // ivr::Loss's value (0 mse, 1 l1, 2 dot: kernels/array_ops.cl loss_partial).
  cl::Event loss(const cl::Buffer& image, const cl::Buffer& target, std::uint64_t n, int kind,
                 const cl::Buffer& out, std::vector<cl::Event>& events);
  cl::Event gather(const cl::Buffer& src, const cl::Buffer& index, int n, const cl::Buffer& dst);
  // dst[i] (acc_dtype()) = per_ray[index[i]] (reals) where index[i] >= 0, else
  // sums[-1 - index[i]] (acc_dtype()), i < n: a forward-mode gradient with ray parameters.
  cl::Event assemble(const cl::Buffer& per_ray, const cl::Buffer& sums, const cl::Buffer& index,
                     std::uint64_t n, const cl::Buffer& dst);
  cl::Event copy_columns(std::uint64_t rows, const cl::Buffer& src, int src_cols, int src_first,
                         const cl::Buffer& dst, int dst_cols, int dst_first, int count);
  // n values between float32 and float64 (only where the device has float64).
  cl::Event convert(const cl::Buffer& src, DType from, const cl::Buffer& dst, DType to,
                    std::uint64_t n);

 private:
  Device::Impl& dev_;
  KernelSet& kernels_;
  bool f64_, acc_f64_;
  cl::Kernel& kernel(const char* entry);
  cl::Buffer scratch_;  // the reductions' partial sums
  std::size_t scratch_bytes_ = 0;
  cl::Buffer check_min_, check_max_, check_bad_;  // check_values' per-group results
  std::size_t check_groups_ = 0;
  const cl::Buffer& scratch(std::size_t bytes);
};

}  // namespace ivr
