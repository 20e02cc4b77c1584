// mpi_world.hpp — the processes of an `mpirun` (docs/scaling.md): data-parallel over views (each
// rank renders or differentiates its share of the views, rank 0 gathers and writes) or over slabs
// of the volume (the rays' states exchanged between ranks). Built on Open
// MPI where the build found it (IVR_WITH_MPI); one process otherwise, and whenever the tool was
// not started by mpirun.
#pragma once
#include <string>
#include <vector>

#include "ivr/domain.hpp"

namespace ivr::cli {

struct World {
  int rank = 0, size = 1;
  // Over slabs: the ranks' weights, each rank's slab of the planes in proportion
  // (domain_slab; set by weigh_rank_slabs before a rank loads its slab); empty: equal slabs.
  std::vector<double> slab_shares;
};
const World& world();

// MPI_Init where started by mpirun (and built with MPI); mpi_end() finalises.
void mpi_begin(int* argc, char*** argv);
void mpi_end();
// On an error in one rank: ends every rank (a collective would wait for it forever).
[[noreturn]] void mpi_abort(int status);

// Σ over ranks, every rank getting the sum.
void sum_all(std::vector<double>& values);
// Every rank's `mine` by rank, on every rank (exact: each in its own slot of a sum).
std::vector<double> every_rank(double mine);
// Every rank's values joined in rank order, on rank 0 (others get an empty vector).
std::vector<double> gather(const std::vector<double>& mine);
// Every rank's values by rank, on rank 0 (others get an empty vector).
std::vector<std::vector<double>> gather_parts(const std::vector<double>& mine);
// Every rank's bytes by rank, on every rank (MPI_Allgatherv).
std::vector<std::vector<unsigned char>> all_gather(const std::vector<unsigned char>& mine);
// The ranks' slabs under mpirun over slabs sized by `shares` from here on (load_scene_for,
// domain_part): every rank passing the same.
void set_slab_shares(const std::vector<double>& shares);
// This rank's part of a domain-parallel operation over the world (--split slabs or segments:
// SlabMarch::states or segments), and its one device (several are refused).
DomainPart domain_part(const std::string& split = "slabs");
// The scene file with, under --split slabs or segments, only this rank's slab of its volume read (the planes
// domain_slab gives it: domain_share's convention), else whole.
Scene load_scene_for(const std::string& path, const std::string& split);
Device& one_device_per_rank(const std::vector<Device*>& devices);

}  // namespace ivr::cli
