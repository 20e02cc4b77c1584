// ivr/phantom.hpp — test volumes for tomography: the 3D Shepp–Logan head of Kak & Slaney and
// random ellipsoids, sampled at the voxel centres of a cube over [-1, 1]³.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "ivr/export.h"
#include "ivr/scene.hpp"

namespace ivr {

// One ellipsoid: centre and semi-axes in [-1, 1]³ coordinates, rotation `phi_degrees` about z
// (counter-clockwise seen from +z), and the value it adds inside.
struct Ellipsoid {
  double x0 = 0, y0 = 0, z0 = 0;
  double a = 1, b = 1, c = 1;
  double phi_degrees = 0;
  double value = 0;
};

// The sum of the ellipsoids' values at every voxel centre of an n³ cube over [-1, 1]³
// (voxel i at −1 + (2i + 1)/n); shape (n, n, n), x fastest, spacing (1, 1, 1). Throws
// ivr::Error(invalid_argument) for n < 1, over 2^31 voxels, or an ellipsoid with a non-positive
// semi-axis or a non-finite field. supersample s > 1 (up to 16): each voxel is instead the mean
// over s³ points at the centres of its sub-cells (the cell average, as a detector-sized voxel
// would see the continuous phantom; fewer aliased edges for solvers to chase).
IVR_API Volume phantom_from_ellipsoids(const std::vector<Ellipsoid>& ellipsoids, int n,
                                       int supersample = 1);
// The same on an nx × ny × nz grid, each axis over [-1, 1] (x at −1 + (2i + 1)/nx, …): the
// scene's "synthetic": "shepp_logan" for any dims (the box then stretches the phantom).
IVR_API Volume phantom_from_ellipsoids(const std::vector<Ellipsoid>& ellipsoids, int nx, int ny,
                                       int nz, int supersample = 1);

// The 3D Shepp–Logan phantom of Kak & Slaney (Principles of Computerized Tomographic Imaging,
// Table 3.1, 3D): skull 2.0, brain 1.02, features adding ±0.01–0.02.
IVR_API std::vector<Ellipsoid> shepp_logan_ellipsoids();

// `count` (0..100000) random ellipsoids inside the unit ball, values in [0.1, 1] (non-negative
// sums), from a platform-independent generator seeded with `seed` (the same ellipsoids on every
// machine).
IVR_API std::vector<Ellipsoid> random_ellipsoids(int count, std::uint64_t seed);

// By name: "shepp-logan" or "ellipsoids" (10 random ellipsoids from `seed`); throws
// ivr::Error(invalid_argument) naming the known ones, or for n outside 1..1024.
IVR_API Volume phantom(const std::string& name, int n, std::uint64_t seed = 1, int supersample = 1);

}  // namespace ivr
