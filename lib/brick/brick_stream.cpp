// brick_stream.cpp — bricks through device slots, uploads overlapped with the kernels.
#include "brick/brick_stream.hpp"

#include <algorithm>

namespace ivr {

BrickStream::BrickStream(Device::Impl& dev, int slots, std::size_t slot_bytes) : dev_(dev) {
  uploads_ = cl_call("creating the upload queue on " + dev.info.name,
                     [&] { return cl::CommandQueue(dev.context, dev.device, 0); });
  slot_.resize(std::max(slots, 1));
  for (Slot& s : slot_)
    s.buffer = dev.buffer(CL_MEM_READ_ONLY, slot_bytes, nullptr, "a brick of the volume");
}

int BrickStream::resident(int b,
                          const std::function<void(int, std::vector<unsigned char>&)>& fill) {
  for (int i = 0; i < int(slot_.size()); ++i)
    if (slot_[i].brick == b) return slot_[i].used = ++clock_, i;
  const int i = int(std::min_element(slot_.begin(), slot_.end(),
                                     [](const Slot& a, const Slot& c) { return a.used < c.used; }) -
                    slot_.begin());
  Slot& s = slot_[i];
  return cl_call("streaming a brick to " + dev_.info.name, [&] {
    if (!s.uses.empty()) cl::WaitForEvents(s.uses);  // the kernels that read its last brick
    s.uses.clear();
    if (s.write()) s.write.wait();  // its staging memory is free again
    fill(b, s.staging);
    uploads_.enqueueWriteBuffer(s.buffer, CL_FALSE, 0, s.staging.size(), s.staging.data(),
                                nullptr, &s.write);
    uploads_.flush();
    uploaded_bytes += s.staging.size();
    ++uploads;
    s.brick = b;
    s.used = ++clock_;
    return i;
  });
}

}  // namespace ivr
