// brick_stream.hpp — internal: bricks streamed through a few device slots: each brick copied out of
// the host volume into a slot's staging memory and uploaded on a queue of its own, a slot refilled
// (least recently used first) only once the kernels that read it are done, so that the host's copy
// and the upload of the next brick overlap the kernels of the current one.
#pragma once
#include <CL/opencl.hpp>
#include <cstdint>
#include <functional>
#include <vector>

#include "runtime/runtime.hpp"

namespace ivr {

class BrickStream {
 public:
  // `slots` device buffers of `slot_bytes` each.
  BrickStream(Device::Impl& dev, int slots, std::size_t slot_bytes);

  // The slot holding brick b, filling it through fill(b, staging) and uploading it where none
  // does. Kernels that read the slot wait for ready(slot) and are handed to used().
  int resident(int b, const std::function<void(int, std::vector<unsigned char>&)>& fill);
  const cl::Buffer& buffer(int slot) const { return slot_[slot].buffer; }
  const cl::Event& ready(int slot) const { return slot_[slot].write; }
  void used(int slot, const cl::Event& kernel) { slot_[slot].uses.push_back(kernel); }

  std::uint64_t uploaded_bytes = 0, uploads = 0;

 private:
  struct Slot {
    cl::Buffer buffer;
    int brick = -1;
    long used = -1;
    std::vector<cl::Event> uses;
    cl::Event write;
    std::vector<unsigned char> staging;
  };
  Device::Impl& dev_;
  cl::CommandQueue uploads_;
  std::vector<Slot> slot_;
  long clock_ = 0;
};

}  // namespace ivr
