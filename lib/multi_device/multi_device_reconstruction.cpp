// multi_device_reconstruction.cpp — a reconstruction over several devices of one process
// (MultiDeviceReconstruction, ivr/reconstruct.hpp): each device a worker of its own — a slab of
// the volume, or a share of each batch's views — every step run on the devices' threads together,
// their sums and all-gathers meeting in the process.
#include <algorithm>
#include <memory>

#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "ivr/reconstruct.hpp"
#include "multi_device/run_shares.hpp"

namespace ivr {

struct MultiDeviceReconstruction::Impl {
  std::vector<Device*> devices;
  WorkerSum sum;
  WorkerGather gather;
  std::vector<std::unique_ptr<Reconstruction>> workers;
  std::vector<IterationRecord> records;
  bool failed = false;

  explicit Impl(const std::vector<Device*>& d)
      : devices(d), sum(int(d.size())), gather(int(d.size())), workers(d.size()),
        records(d.size()) {}

  // job(i) on every device's thread; a device that fails stops the others' collectives, and the
  // object is then of no further use (the devices' states may differ).
  template <class Job>
  void each(const char* what, Job&& job) {
    if (failed)
      throw Error(Status::invalid_argument, std::string("MultiDeviceReconstruction::") + what +
                                                ": a device failed before; make a new one");
    try {
      run_shares(devices.size(), job, [this] {
        sum.abort();
        gather.abort();
      });
    } catch (...) {
      failed = true;
      throw;
    }
  }
};

MultiDeviceReconstruction::MultiDeviceReconstruction(const std::vector<Device*>& devices,
                                                     const Scene& scene, const Image& targets,
                                                     const ReconstructOptions& options) {
  check_devices(devices);
  if (options.workers != 1 || options.worker != 0 || options.sum || options.all_gather)
    throw Error(Status::invalid_argument,
                "MultiDeviceReconstruction: options.worker, workers, sum and all_gather are the "
                "devices'; leave them unset");
  // Over views, the devices whose share of a batch is not empty (by their weights), each with its
  // weight; over slabs every device, its slab by its weight.
  std::vector<Device*> taking = devices;
  std::vector<double> weights;
  if (!options.slabs && !scene.has_ray_list()) {  // (a ray list: refused by the workers)
    const int views = image_extent(scene).views;
    const int batch = options.batch > 0 ? std::min(options.batch, views) : views;
    std::vector<std::pair<std::size_t, std::size_t>> parts;
    taking.clear();
    for (std::size_t i : active_shares(devices, std::size_t(std::max(batch, 0)), options.shares,
                                       parts, &weights))
      taking.push_back(devices[i]);
    if (taking.empty()) taking.push_back(devices[0]);  // (no views: the worker says so)
  }
  const int n = int(taking.size());
  // Over slabs each device's share of the planes by its weight (equal speeds: equal slabs); more
  // devices than cells, or a bad weight, said before any thread starts.
  if (options.slabs) {
    weights = share_weights(devices, options.shares);
    domain_slab(scene.volume.nz, 0, n, weights);
  }
  impl_ = std::make_unique<Impl>(taking);
  Impl& m = *impl_;
  m.each("MultiDeviceReconstruction", [&](std::size_t i) {
    ReconstructOptions o = options;
    o.worker = int(i), o.workers = n;
    o.shares = n > 1 ? weights : std::vector<double>{};
    o.sum = m.sum.of(int(i));
    if (o.slabs) o.all_gather = m.gather.of(int(i));
    m.workers[i] = std::make_unique<Reconstruction>(
        *taking[i], o.slabs ? domain_share(scene, int(i), n, o.shares) : scene, targets, o);
  });
}

MultiDeviceReconstruction::~MultiDeviceReconstruction() = default;
MultiDeviceReconstruction::MultiDeviceReconstruction(MultiDeviceReconstruction&&) noexcept =
    default;
MultiDeviceReconstruction& MultiDeviceReconstruction::operator=(
    MultiDeviceReconstruction&&) noexcept = default;

const IterationRecord& MultiDeviceReconstruction::step() {
  Impl& m = *impl_;
  if (done()) throw Error(Status::invalid_argument, "MultiDeviceReconstruction::step: already done");
  m.each("step", [&](std::size_t i) { m.records[i] = m.workers[i]->step(); });
  return m.workers[0]->history().back();
}

bool MultiDeviceReconstruction::done() const { return impl_->workers[0]->done(); }
int MultiDeviceReconstruction::iteration() const { return impl_->workers[0]->iteration(); }
const std::vector<IterationRecord>& MultiDeviceReconstruction::history() const {
  return impl_->workers[0]->history();
}
int MultiDeviceReconstruction::devices() const { return int(impl_->devices.size()); }
const ReconstructOptions& MultiDeviceReconstruction::options() const {
  return impl_->workers[0]->options();
}
int MultiDeviceReconstruction::levels() const { return impl_->workers[0]->levels(); }
std::vector<int> MultiDeviceReconstruction::level_dims(int level) const {
  return impl_->workers[0]->level_dims(level);
}

Scene MultiDeviceReconstruction::result() const {
  if (!impl_->workers[0]->options().slabs) return impl_->workers[0]->result();  // (all alike)
  std::vector<std::vector<double>> slabs;
  Scene out;
  for (const std::unique_ptr<Reconstruction>& w : impl_->workers) {
    Scene part = w->result();  // (the level's grid described whole, this device's planes)
    slabs.emplace_back(part.volume.data.begin(), part.volume.data.end());
    if (slabs.size() == 1) out = std::move(part);
  }
  const std::vector<double> whole =
      domain_assemble(out.volume.nx, out.volume.ny, out.volume.nz, slabs);
  out.volume.data.assign(whole.begin(), whole.end());
  return out;
}

void MultiDeviceReconstruction::save_checkpoint(const std::string& prefix) const {
  Impl& m = *impl_;
  run_shares(m.devices.size(), [&](std::size_t i) {
    m.workers[i]->save_checkpoint(prefix + "_device" + std::to_string(i));
  });
}

void MultiDeviceReconstruction::remove_checkpoint(const std::string& prefix, int devices) {
  for (int i = 0; i < devices; ++i)
    Reconstruction::remove_checkpoint(prefix + "_device" + std::to_string(i));
}

void MultiDeviceReconstruction::resume(const std::string& prefix) {
  Impl& m = *impl_;
  m.each("resume", [&](std::size_t i) {
    m.workers[i]->resume(prefix + "_device" + std::to_string(i));
  });
}

}  // namespace ivr
