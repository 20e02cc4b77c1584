// device_array.cpp — device arrays (shape, type, buffer; uploads and downloads with conversion)
// and the array kernels of kernels/array_ops.cl.
#include "runtime/device_array.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "ivr/error.hpp"

namespace ivr {

namespace {

constexpr std::size_t kReduceSize = 256;  // IVR_REDUCE_SIZE

[[noreturn]] void bad(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

const DeviceArray::Impl& live(const DeviceArray& a, const char* what) {
  if (!a.valid()) bad(std::string(what) + ": the device array is empty (never made, or moved)");
  return *a.impl();
}

template <class T>
void upload_as(DeviceArray::Impl& a, const T* values, std::size_t count) {
  if (!values) bad("upload: values is null");
  if (a.host && a.host->maps > 0) bad("upload: the device array is mapped (unmap it first)");
  if (count != a.size)
    bad("upload: " + std::to_string(count) + " values for an array of " + std::to_string(a.size) +
        " " + shape_text(a.shape));
  cl_call("uploading a device array", [&] {
    cl::Event done;
    if (dtype_size(a.dtype) == sizeof(T)) {
      a.dev->queue.enqueueWriteBuffer(a.buffer, CL_TRUE, 0, a.size * sizeof(T), values, nullptr,
                                      &done);
    } else if (a.dtype == DType::f32) {
      const std::vector<float> converted(values, values + count);
      a.dev->queue.enqueueWriteBuffer(a.buffer, CL_TRUE, 0, a.size * 4, converted.data(), nullptr,
                                      &done);
    } else {
      const std::vector<double> converted(values, values + count);
      a.dev->queue.enqueueWriteBuffer(a.buffer, CL_TRUE, 0, a.size * 8, converted.data(), nullptr,
                                      &done);
    }
    a.written = done;
  });
}

template <class T>
void download_as(const DeviceArray::Impl& a, T* values, std::size_t count) {
  if (!values) bad("download: values is null");
  if (count < a.size)
    bad("download: room for " + std::to_string(count) + " values; the array " +
        shape_text(a.shape) + " has " + std::to_string(a.size));
  if (a.size == 0) return;
  cl_call("reading a device array back", [&] {
    if (dtype_size(a.dtype) == sizeof(T)) {
      a.dev->queue.enqueueReadBuffer(a.buffer, CL_TRUE, 0, a.size * sizeof(T), values);
    } else if (a.dtype == DType::f32) {
      std::vector<float> raw(a.size);
      a.dev->queue.enqueueReadBuffer(a.buffer, CL_TRUE, 0, a.size * 4, raw.data());
      std::copy(raw.begin(), raw.end(), values);
    } else {
      std::vector<double> raw(a.size);
      a.dev->queue.enqueueReadBuffer(a.buffer, CL_TRUE, 0, a.size * 8, raw.data());
      std::transform(raw.begin(), raw.end(), values, [](double v) { return T(v); });
    }
  });
}

}  // namespace

const char* dtype_name(DType dtype) {
  return dtype == DType::f64 ? "float64" : "float32";
}

std::size_t dtype_size(DType dtype) {
  return dtype == DType::f64 ? 8 : 4;
}

DType real_dtype(bool f64) {
  return f64 ? DType::f64 : DType::f32;
}

std::string shape_text(const std::vector<std::int64_t>& shape) {
  std::ostringstream s;
  s << "(";
  for (std::size_t i = 0; i < shape.size(); ++i) s << (i ? ", " : "") << shape[i];
  s << (shape.size() == 1 ? ",)" : ")");
  return s.str();
}

DeviceArray make_array(const Device& device, Device::Impl& dev, std::vector<std::int64_t> shape,
                       DType dtype, const char* what, void* host) {
  auto a = std::make_shared<DeviceArray::Impl>();
  std::size_t n = 1;
  for (std::int64_t d : shape) {
    if (d < 0 || (d > 0 && n > std::numeric_limits<std::size_t>::max() / 16 / std::size_t(d)))
      bad(std::string(what) + ": shape " + shape_text(shape) + " is negative or too large");
    n *= std::size_t(d);
  }
  if (dtype == DType::f64 && !dev.info.fp64)
    throw Error(Status::unsupported,
                "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
  a->device = &device;
  a->dev = &dev;
  a->shape = std::move(shape);
  a->dtype = dtype;
  a->size = n;
  const std::size_t bytes = n * dtype_size(dtype);
  host = bytes > 0 ? host : nullptr;  // an empty array has no memory to share
  a->buffer = dev.buffer(CL_MEM_READ_WRITE | (host ? CL_MEM_USE_HOST_PTR : 0), bytes, host, what);
  a->host = std::make_shared<HostAccess>();
  a->host->borrowed = host != nullptr;
  a->host->buffer = a->buffer;
  a->host->queue = dev.queue;
  a->host->bytes = std::max<std::size_t>(bytes, 1);
  return DeviceArray(std::move(a));
}

HostAccess::~HostAccess() {
  // Destructors do not throw: a device lost here has failed the operations that used it already.
  try {
    if (maps > 0 && mapped) queue.enqueueUnmapMemObject(buffer, mapped);
    if (borrowed || maps > 0) queue.finish();  // no command reads the caller's memory any more
  } catch (...) {
  }
}

DeviceArray DeviceArray::wrap(Device& device, void* host, std::vector<std::int64_t> shape,
                              DType dtype) {
  if (!host) bad("wrap: the host memory is null");
  Device::Impl& dev = device.impl();
  if (!dev.info.host_unified_memory) {  // one copy in, into a buffer of the device's own
    DeviceArray a = make_array(device, dev, std::move(shape), dtype, "a wrapped array");
    if (a.dtype() == DType::f32)
      a.upload(static_cast<const float*>(host), a.size());
    else
      a.upload(static_cast<const double*>(host), a.size());
    return a;
  }
  // The caller's memory itself (CL_MEM_USE_HOST_PTR): the driver uses it as the buffer.
  return make_array(device, dev, std::move(shape), dtype, "a wrapped array", host);
}

bool DeviceArray::borrowed() const {
  return live(*this, "borrowed").host->borrowed;
}

void* DeviceArray::map() const {
  const Impl& a = live(*this, "map");
  HostAccess& h = *a.host;
  std::lock_guard<std::mutex> lock(h.mutex);
  if (h.maps == 0)
    h.mapped = cl_call("mapping a device array into host memory", [&] {
      // Blocking, on the in-order queue: every command enqueued before it (its writers) is done.
      return a.dev->queue.enqueueMapBuffer(h.buffer, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0,
                                           h.bytes);
    });
  ++h.maps;
  return h.mapped;
}

void DeviceArray::unmap() const {
  const Impl& a = live(*this, "unmap");
  HostAccess& h = *a.host;
  std::lock_guard<std::mutex> lock(h.mutex);
  if (h.maps == 0) bad("unmap: the device array is not mapped");
  if (--h.maps == 0) {
    cl_call("unmapping a device array", [&] {
      cl::Event done;
      a.dev->queue.enqueueUnmapMemObject(h.buffer, h.mapped, nullptr, &done);
      done.wait();
    });
    h.mapped = nullptr;
  }
}

DeviceArray reshape(const DeviceArray& array, std::vector<std::int64_t> shape) {
  std::size_t n = 1;
  for (std::int64_t d : shape) n *= std::size_t(std::max<std::int64_t>(d, 0));
  if (n != array.size())
    bad("reshape: " + shape_text(shape) + " does not hold the " + std::to_string(array.size()) +
        " values of " + shape_text(array.shape()));
  auto view = std::make_shared<DeviceArray::Impl>(*array.impl());
  view->shape = std::move(shape);
  view->base = array.impl()->base ? array.impl()->base : array.impl();
  return DeviceArray(std::move(view));
}

DeviceArray::DeviceArray(Device& device, std::vector<std::int64_t> shape, DType dtype)
    : DeviceArray(make_array(device, device.impl(), std::move(shape), dtype, "a device array")) {
  cl_call("zeroing a device array", [&] {
    if (impl_->size == 0) return;
    cl::Event done;
    impl_->dev->queue.enqueueFillBuffer(impl_->buffer, cl_uchar(0), 0,
                                        impl_->size * dtype_size(impl_->dtype), nullptr, &done);
    impl_->written = done;
  });
}

const std::vector<std::int64_t>& DeviceArray::shape() const {
  return live(*this, "shape").shape;
}
DType DeviceArray::dtype() const {
  return live(*this, "dtype").dtype;
}
std::size_t DeviceArray::size() const {
  return live(*this, "size").size;
}
std::size_t DeviceArray::bytes() const {
  const Impl& a = live(*this, "bytes");
  return a.size * dtype_size(a.dtype);
}
void DeviceArray::upload(const float* values, std::size_t count) {
  live(*this, "upload");
  upload_as(*impl_, values, count);
}
void DeviceArray::upload(const double* values, std::size_t count) {
  live(*this, "upload");
  upload_as(*impl_, values, count);
}
void DeviceArray::download(float* values, std::size_t count) const {
  download_as(live(*this, "download"), values, count);
}
void DeviceArray::download(double* values, std::size_t count) const {
  download_as(live(*this, "download"), values, count);
}
std::vector<float> DeviceArray::to_floats() const {
  std::vector<float> out(size());
  download(out.data(), out.size());
  return out;
}
std::vector<double> DeviceArray::to_doubles() const {
  std::vector<double> out(size());
  download(out.data(), out.size());
  return out;
}
void DeviceArray::wait() const {
  const Impl& a = live(*this, "wait");
  cl_call("waiting for a device array", [&] {
    if (a.written()) a.written.wait();
  });
}
bool DeviceArray::on(const Device& device) const {
  return valid() && impl_->device == &device;
}

// --- the array kernels --------------------------------------------------------------------------

ArrayKernels::ArrayKernels(Device::Impl& dev, KernelSet& kernels, bool f64)
    : dev_(dev), kernels_(kernels), f64_(f64), acc_f64_(dev.info.fp64) {}

cl::Kernel& ArrayKernels::kernel(const char* entry) {
  KernelConfig c("array_ops.cl", entry);
  c.set(Switch::f64, f64_).set(Switch::acc_f64, acc_f64_).set(Switch::reduce_size, int(kReduceSize));
  return kernels_.get(c);
}

const cl::Buffer& ArrayKernels::scratch(std::size_t bytes) {
  if (bytes > scratch_bytes_) {
    scratch_ = dev_.buffer(CL_MEM_READ_WRITE, bytes, nullptr, "the reductions' partial sums");
    scratch_bytes_ = bytes;
  }
  return scratch_;
}

namespace {
// $IVR_CHECK_LAYOUT=chunks|strided overrides the device type's choice (tests run both anywhere).
bool check_in_chunks(const DeviceInfo& info) {
  const char* env = std::getenv("IVR_CHECK_LAYOUT");
  if (!env || !*env) return info.type == "cpu";
  const std::string v = env;
  if (v != "chunks" && v != "strided")
    throw Error(Status::invalid_argument,
                "IVR_CHECK_LAYOUT must be chunks or strided, got '" + v + "'");
  return v == "chunks";
}

// Work-groups for a grid-stride pass over n elements: enough to fill the device, few enough
// that the partials are small.
std::size_t pass_groups(const DeviceInfo& info, std::uint64_t n) {
  const std::uint64_t wanted = (n + kReduceSize * 16 - 1) / (kReduceSize * 16);
  const std::uint64_t most = std::max<std::uint64_t>(4 * std::uint64_t(info.compute_units), 64);
  return std::size_t(std::clamp<std::uint64_t>(wanted, 1, std::min<std::uint64_t>(most, 1024)));
}
}  // namespace

std::uint64_t ArrayKernels::check_values(const cl::Buffer& values, std::uint64_t n,
                                         bool allow_negative, double* lo, double* hi,
                                         std::vector<cl::Event>& events) {
  const std::size_t groups = pass_groups(dev_.info, n), real = f64_ ? 8 : 4;
  // The groups' minima, maxima and first bad indices, one after another in the scratch buffer
  // (offsets of sub-buffers would need the device's alignment: three buffers of one scratch).
  if (check_groups_ < groups) {
    check_min_ = dev_.buffer(CL_MEM_READ_WRITE, groups * real, nullptr, "the check's minima");
    check_max_ = dev_.buffer(CL_MEM_READ_WRITE, groups * real, nullptr, "the check's maxima");
    check_bad_ = dev_.buffer(CL_MEM_READ_WRITE, groups * 8, nullptr, "the check's indices");
    check_groups_ = groups;
  }
  return cl_call("checking values on " + dev_.info.name, [&] {
    cl::Kernel& k = kernel("volume_check");
    // CPU devices: a contiguous chunk per work-item (PoCL runs an item's loop as scalar code,
    // and a strided one touches a new cache line per element: 0.5 GB/s at 512³ on 2 cores);
    // elsewhere neighbouring items read neighbouring elements.
    const std::uint64_t items = std::uint64_t(groups) * kReduceSize;
    const std::uint64_t chunk = check_in_chunks(dev_.info) ? (n + items - 1) / items : 0;
    k.setArg(0, cl_ulong(n));
    k.setArg(1, cl_ulong(chunk));
    k.setArg(2, values);
    k.setArg(3, cl_int(allow_negative ? 1 : 0));
    k.setArg(4, check_min_);
    k.setArg(5, check_max_);
    k.setArg(6, check_bad_);
    events.push_back(enqueue_groups(dev_, k, groups, kReduceSize));
    std::vector<cl_ulong> first(groups);
    std::vector<double> a(groups), b(groups);
    dev_.queue.enqueueReadBuffer(check_bad_, CL_FALSE, 0, groups * 8, first.data());
    if (f64_) {
      dev_.queue.enqueueReadBuffer(check_min_, CL_FALSE, 0, groups * 8, a.data());
      dev_.queue.enqueueReadBuffer(check_max_, CL_TRUE, 0, groups * 8, b.data());
    } else {
      std::vector<float> fa(groups), fb(groups);
      dev_.queue.enqueueReadBuffer(check_min_, CL_FALSE, 0, groups * 4, fa.data());
      dev_.queue.enqueueReadBuffer(check_max_, CL_TRUE, 0, groups * 4, fb.data());
      std::copy(fa.begin(), fa.end(), a.begin());
      std::copy(fb.begin(), fb.end(), b.begin());
    }
    *lo = *std::min_element(a.begin(), a.end());
    *hi = *std::max_element(b.begin(), b.end());
    return std::uint64_t(*std::min_element(first.begin(), first.end()));
  });
}

cl::Event ArrayKernels::sum_rows(const cl::Buffer& in, int rows, int cols, int blocks,
                                 const cl::Buffer& out) {
  cl::Kernel& k = kernel("sum_rows");
  k.setArg(0, in);
  k.setArg(1, cl_int(rows));
  k.setArg(2, cl_int(cols));
  k.setArg(3, out);
  return enqueue_groups(dev_, k, std::size_t(blocks), kReduceSize);
}

cl::Event ArrayKernels::loss(const cl::Buffer& image, const cl::Buffer& target, std::uint64_t n,
                             int kind, const cl::Buffer& out, std::vector<cl::Event>& events) {
  const std::size_t groups = pass_groups(dev_.info, n);
  const cl::Buffer& partial = scratch(groups * (acc_f64_ ? 8 : 4));
  cl::Kernel& k = kernel("loss_partial");
  k.setArg(0, cl_ulong(n));
  k.setArg(1, image);
  k.setArg(2, target);
  const double norm = kind == 2 ? 1.0 : 1.0 / double(n);  // dot: a sum, not a mean
  if (acc_f64_)
    k.setArg(3, cl_double(norm));
  else
    k.setArg(3, cl_float(norm));
  k.setArg(4, cl_int(kind));
  k.setArg(5, partial);
  events.push_back(enqueue_groups(dev_, k, groups, kReduceSize));
  cl::Kernel& sum = kernel("sum_acc_rows");
  sum.setArg(0, partial);
  sum.setArg(1, cl_int(groups));
  sum.setArg(2, cl_int(1));
  sum.setArg(3, out);
  events.push_back(enqueue_groups(dev_, sum, 1, kReduceSize));
  return events.back();
}

cl::Event ArrayKernels::gather(const cl::Buffer& src, const cl::Buffer& index, int n,
                               const cl::Buffer& dst) {
  cl::Kernel& k = kernel("gather");
  k.setArg(0, cl_int(n));
  k.setArg(1, src);
  k.setArg(2, index);
  k.setArg(3, dst);
  return enqueue_1d(dev_, k, std::size_t(n), 64);
}

cl::Event ArrayKernels::assemble(const cl::Buffer& per_ray, const cl::Buffer& sums,
                                 const cl::Buffer& index, std::uint64_t n, const cl::Buffer& dst) {
  cl::Kernel& k = kernel("assemble");
  k.setArg(0, cl_ulong(n));
  k.setArg(1, per_ray);
  k.setArg(2, sums);
  k.setArg(3, index);
  k.setArg(4, dst);
  return enqueue_1d(dev_, k, std::size_t(n), 64);
}

cl::Event ArrayKernels::copy_columns(std::uint64_t rows, const cl::Buffer& src, int src_cols,
                                     int src_first, const cl::Buffer& dst, int dst_cols,
                                     int dst_first, int count) {
  cl::Kernel& k = kernel("copy_columns");
  k.setArg(0, cl_ulong(rows));
  k.setArg(1, src);
  k.setArg(2, cl_int(src_cols));
  k.setArg(3, cl_int(src_first));
  k.setArg(4, dst);
  k.setArg(5, cl_int(dst_cols));
  k.setArg(6, cl_int(dst_first));
  k.setArg(7, cl_int(count));
  return enqueue_1d(dev_, k, std::size_t(rows), 64);
}

cl::Event ArrayKernels::convert(const cl::Buffer& src, DType from, const cl::Buffer& dst, DType to,
                                std::uint64_t n) {
  if (from == to) {
    cl::Event done;
    dev_.queue.enqueueCopyBuffer(src, dst, 0, 0, std::size_t(n) * dtype_size(from), nullptr,
                                 &done);
    return done;
  }
  if (!acc_f64_)
    throw Error(Status::unsupported,
                "device " + dev_.info.name + " has no float64 support (cl_khr_fp64)");
  cl::Kernel& k = kernel(from == DType::f32 ? "float_to_double" : "double_to_float");
  k.setArg(0, cl_ulong(n));
  k.setArg(1, src);
  k.setArg(2, dst);
  return enqueue_1d(dev_, k, std::size_t(n), 64);
}

}  // namespace ivr
