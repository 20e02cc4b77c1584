// mpi_world.cpp — Open MPI where built with it, a single process otherwise.
#include "mpi_world.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <string>

#include "ivr/error.hpp"

#ifdef IVR_WITH_MPI
#include <mpi.h>
#endif

namespace ivr::cli {

namespace {
World the_world;
bool started = false;
}  // namespace

const World& world() { return the_world; }

void mpi_begin(int* argc, char*** argv) {
#ifdef IVR_WITH_MPI
  // Only under a launcher: a plain `ivr` run stays one process without MPI's start-up.
  if (!std::getenv("OMPI_COMM_WORLD_SIZE") && !std::getenv("PMIX_RANK") && !std::getenv("PMI_RANK"))
    return;
  MPI_Init(argc, argv);
  started = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &the_world.rank);
  MPI_Comm_size(MPI_COMM_WORLD, &the_world.size);
#else
  (void)argc, (void)argv;
#endif
}

void mpi_end() {
#ifdef IVR_WITH_MPI
  if (started) MPI_Finalize();
#endif
  started = false;
}

void mpi_abort(int status) {
#ifdef IVR_WITH_MPI
  if (started && the_world.size > 1) MPI_Abort(MPI_COMM_WORLD, status);
#endif
  std::exit(status);
}

void sum_all(std::vector<double>& values) {
#ifdef IVR_WITH_MPI
  if (started && the_world.size > 1)
    MPI_Allreduce(MPI_IN_PLACE, values.data(), int(values.size()), MPI_DOUBLE, MPI_SUM,
                  MPI_COMM_WORLD);
#else
  (void)values;
#endif
}

std::vector<double> every_rank(double mine) {
  std::vector<double> out(std::size_t(the_world.size), 0.0);
  out[std::size_t(the_world.rank)] = mine;
  sum_all(out);  // (x + 0 + ... + 0 = x exactly)
  return out;
}

namespace {
// Every rank's values joined in rank order on rank 0 (others: empty), and how many each sent.
std::vector<double> gather_counted(const std::vector<double>& mine, std::vector<int>& counts) {
  counts.assign(1, int(mine.size()));
#ifdef IVR_WITH_MPI
  if (started && the_world.size > 1) {
    int count = int(mine.size());
    counts.assign(std::size_t(the_world.size), 0);
    std::vector<int> offsets(the_world.size);
    MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
    std::vector<double> all;
    if (the_world.rank == 0) {
      int at = 0;
      for (int r = 0; r < the_world.size; ++r) offsets[r] = at, at += counts[r];
      all.resize(std::size_t(at));
    } else {
      counts.clear();
    }
    MPI_Gatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), offsets.data(),
                MPI_DOUBLE, 0, MPI_COMM_WORLD);
    return all;
  }
#endif
  return mine;
}
}  // namespace

std::vector<double> gather(const std::vector<double>& mine) {
  std::vector<int> counts;
  return gather_counted(mine, counts);
}

std::vector<std::vector<double>> gather_parts(const std::vector<double>& mine) {
  std::vector<int> counts;
  const std::vector<double> all = gather_counted(mine, counts);
  std::vector<std::vector<double>> parts;
  std::size_t at = 0;
  for (int c : counts) {
    parts.emplace_back(all.begin() + std::ptrdiff_t(at), all.begin() + std::ptrdiff_t(at + c));
    at += std::size_t(c);
  }
  return parts;
}

std::vector<std::vector<unsigned char>> all_gather(const std::vector<unsigned char>& mine) {
#ifdef IVR_WITH_MPI
  if (started && the_world.size > 1) {
    int count = int(mine.size());
    std::vector<int> counts(the_world.size), offsets(the_world.size);
    MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
    int total = 0;
    for (int r = 0; r < the_world.size; ++r) offsets[r] = total, total += counts[r];
    std::vector<unsigned char> all(std::size_t(std::max(total, 1)));
    MPI_Allgatherv(mine.data(), count, MPI_BYTE, all.data(), counts.data(), offsets.data(),
                   MPI_BYTE, MPI_COMM_WORLD);
    std::vector<std::vector<unsigned char>> parts;
    for (int r = 0; r < the_world.size; ++r)
      parts.emplace_back(all.begin() + offsets[r], all.begin() + offsets[r] + counts[r]);
    return parts;
  }
#endif
  return {mine};
}

Device& one_device_per_rank(const std::vector<Device*>& devices) {
  if (devices.size() > 1)
    throw Error(Status::invalid_argument, "--split slabs under mpirun: one device per rank, not --device with " +
                                              std::to_string(devices.size()));
  return *devices[0];
}

void set_slab_shares(const std::vector<double>& shares) { the_world.slab_shares = shares; }

Scene load_scene_for(const std::string& path, const std::string& split) {
  if (split == "views") return load_scene(path);
  return load_scene(path, [](int nz) {
    const Slab slab = domain_slab(nz, the_world.rank, the_world.size, the_world.slab_shares);
    return std::pair<int, int>{slab.first, slab.last};
  });
}

DomainPart domain_part(const std::string& split) {
  DomainPart part;
  part.march = split == "segments" ? SlabMarch::segments : SlabMarch::states;
  part.rank = the_world.rank;
  part.ranks = the_world.size;
  part.all_gather = [](const std::vector<unsigned char>& mine) { return all_gather(mine); };
  part.shares = the_world.slab_shares;
  return part;
}

}  // namespace ivr::cli
