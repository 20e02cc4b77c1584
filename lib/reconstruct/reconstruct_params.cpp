// reconstruct_params.cpp — TF values, bounds and scales for the optimiser; volume resampling
// between coarse-to-fine levels; the error measures reconstructions report.
#include "reconstruct/reconstruct_params.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ivr/error.hpp"
#include "ivr/adjoint.hpp"
#include "ivr/reconstruct.hpp"
#include "ivr/tf_parameters.hpp"
#include "scene/tf_kinds.hpp"

namespace ivr {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}

TfBounds tf_bounds(const TransferFunction& tf, double density_scale) {
  const std::vector<double> v = tf_parameters(tf);
  const std::vector<TfColumnInfo>& columns = tf_kind_info(tf.kind).columns;
  double largest_extinction = 0;
  for (std::size_t i = 0; i < v.size(); ++i)
    if (columns[i % columns.size()].column == TfColumn::extinction)
      largest_extinction = std::max(largest_extinction, v[i]);
  TfBounds b;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const TfColumnInfo& c = columns[i % columns.size()];
    b.lower.push_back(c.lower_in_density_units ? c.lower * density_scale : c.lower);
    b.upper.push_back(c.upper);
    switch (c.scale) {
      case TfScale::unit:
        b.scale.push_back(1);
        break;
      case TfScale::largest_extinction:
        b.scale.push_back(largest_extinction > 0 ? largest_extinction : 1.0);
        break;
      case TfScale::density:
        b.scale.push_back(density_scale);
        break;
      case TfScale::own_magnitude:
        b.scale.push_back(std::max(std::abs(v[i]), 1e-3));
        break;
    }
  }
  return b;
}

double largest_density(const Volume& volume) {
  double s = 0;
  for (float d : volume.data) s = std::max(s, double(d));
  return s;
}

double density_scale(const Scene& scene) {
  // (the volume is read only where the TF's span is its maximum)
  return density_scale(scene.tf,
                       scene.tf.kind == TfKind::identity ? largest_density(scene.volume) : 0.0);
}

double density_scale(const TransferFunction& tf, double largest) {
  double s = 0;
  switch (tf.kind) {
    case TfKind::identity:
      s = largest > 0 ? largest : 1;
      break;
    case TfKind::piecewise_linear:
      for (const TfPoint& p : tf.points) s = std::max(s, std::abs(p.density));
      break;
    case TfKind::table:
      s = std::max(std::abs(tf.range.x), std::abs(tf.range.y));
      break;
    case TfKind::gaussian:
      for (const TfGaussian& g : tf.gaussians) s = std::max(s, std::abs(g.mean) + 2 * g.width);
      break;
  }
  return std::max(s, 1e-3);
}

Volume resample_volume(const Volume& in, int nx, int ny, int nz) {
  if (nx < 1 || ny < 1 || nz < 1 || in.voxel_count() == 0 || in.data.size() != in.voxel_count())
    throw Error(Status::invalid_argument, "resample_volume: empty grid or data of the wrong size");
  Volume out;
  out.nx = nx;
  out.ny = ny;
  out.nz = nz;
  out.spacing = in.spacing * glm::dvec3(double(in.nx) / nx, double(in.ny) / ny, double(in.nz) / nz);
  out.data.resize(out.voxel_count());
  const int fx = std::max(1, (in.nx + nx - 1) / nx), fy = std::max(1, (in.ny + ny - 1) / ny),
            fz = std::max(1, (in.nz + nz - 1) / nz);
  // Trilinear between cell centres, clamped to the edge centres (docs/design.md); u in cells of `in`.
  auto axis = [](double u, int n, int& i0, int& i1, double& w) {
    u = std::clamp(u - 0.5, 0.0, double(n - 1));
    i0 = std::min(int(u), n - 1);
    i1 = std::min(i0 + 1, n - 1);
    w = u - i0;
  };
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        double sum = 0;
        for (int sz = 0; sz < fz; ++sz)
          for (int sy = 0; sy < fy; ++sy)
            for (int sx = 0; sx < fx; ++sx) {
              int x0, x1, y0, y1, z0, z1;
              double wx, wy, wz;
              axis((x + (sx + 0.5) / fx) * in.nx / nx, in.nx, x0, x1, wx);
              axis((y + (sy + 0.5) / fy) * in.ny / ny, in.ny, y0, y1, wy);
              axis((z + (sz + 0.5) / fz) * in.nz / nz, in.nz, z0, z1, wz);
              auto at = [&](int i, int j, int k) { return double(in.at(i, j, k)); };
              const double c00 = at(x0, y0, z0) * (1 - wx) + at(x1, y0, z0) * wx;
              const double c10 = at(x0, y1, z0) * (1 - wx) + at(x1, y1, z0) * wx;
              const double c01 = at(x0, y0, z1) * (1 - wx) + at(x1, y0, z1) * wx;
              const double c11 = at(x0, y1, z1) * (1 - wx) + at(x1, y1, z1) * wx;
              sum += (c00 * (1 - wy) + c10 * wy) * (1 - wz) + (c01 * (1 - wy) + c11 * wy) * wz;
            }
        out.data[(std::size_t(z) * ny + y) * nx + x] = float(sum / (fx * fy * fz));
      }
  return out;
}

double psnr(const Image& image, const Image& reference) {
  const double mse = image_loss(image, reference, Loss::mse);
  return mse > 0 ? 10 * std::log10(1 / mse) : kInf;
}

double relative_volume_error(const Volume& a, const Volume& b) {
  if (a.nx != b.nx || a.ny != b.ny || a.nz != b.nz || a.data.size() != b.data.size())
    throw Error(Status::invalid_argument, "relative_volume_error: the volumes differ in shape");
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    const double d = double(a.data[i]) - double(b.data[i]);
    diff += d * d;
    norm += double(b.data[i]) * double(b.data[i]);
  }
  return norm > 0 ? std::sqrt(diff / norm) : (diff > 0 ? kInf : 0.0);
}

}  // namespace ivr
