// reconstruct_params.cpp — TF values, bounds and scales for the optimiser; volume resampling
// between coarse-to-fine levels; the error measures reconstructions report.
#include "reconstruct/reconstruct_params.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ivr/error.hpp"
#include "ivr/adjoint.hpp"
#include "ivr/reconstruct.hpp"

namespace ivr {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}

std::vector<double> tf_parameters(const TransferFunction& tf) {
  std::vector<double> v;
  switch (tf.kind) {
    case TfKind::identity:
      v = {tf.extinction_scale, tf.color_scale};
      break;
    case TfKind::piecewise_linear:
      for (const TfPoint& p : tf.points)
        v.insert(v.end(), {p.color.x, p.color.y, p.color.z, p.extinction});
      break;
    case TfKind::table:
      for (const glm::dvec4& e : tf.entries) v.insert(v.end(), {e.x, e.y, e.z, e.w});
      break;
    case TfKind::gaussian:
      for (const TfGaussian& g : tf.gaussians)
        v.insert(v.end(), {g.color.x, g.color.y, g.color.z, g.extinction, g.mean, g.width});
      break;
  }
  return v;
}

void set_tf_parameters(TransferFunction& tf, const std::vector<double>& v) {
  if (v.size() != tf_parameters(tf).size())
    throw Error(Status::invalid_argument, "TF values: " + std::to_string(v.size()) +
                                              " values for a TF of " +
                                              std::to_string(tf_parameters(tf).size()));
  switch (tf.kind) {
    case TfKind::identity:
      tf.extinction_scale = v[0];
      tf.color_scale = v[1];
      break;
    case TfKind::piecewise_linear:
      for (std::size_t r = 0; r < tf.points.size(); ++r) {
        tf.points[r].color = {v[4 * r], v[4 * r + 1], v[4 * r + 2]};
        tf.points[r].extinction = v[4 * r + 3];
      }
      break;
    case TfKind::table:
      for (std::size_t r = 0; r < tf.entries.size(); ++r)
        tf.entries[r] = {v[4 * r], v[4 * r + 1], v[4 * r + 2], v[4 * r + 3]};
      break;
    case TfKind::gaussian:
      for (std::size_t r = 0; r < tf.gaussians.size(); ++r) {
        TfGaussian& g = tf.gaussians[r];
        g.color = {v[6 * r], v[6 * r + 1], v[6 * r + 2]};
        g.extinction = v[6 * r + 3];
        g.mean = v[6 * r + 4];
        g.width = v[6 * r + 5];
      }
      break;
  }
}

TfBounds tf_bounds(const TransferFunction& tf, double density_scale) {
  const std::vector<double> v = tf_parameters(tf);
  TfBounds b;
  if (tf.kind == TfKind::identity) {
    b.lower = {0, 0};
    b.upper = {kInf, kInf};
    b.scale = {std::max(std::abs(v[0]), 1e-3), std::max(std::abs(v[1]), 1e-3)};
    return b;
  }
  const std::size_t cols = tf.kind == TfKind::gaussian ? 6 : 4;
  double max_extinction = 0;
  for (std::size_t i = 3; i < v.size(); i += cols) max_extinction = std::max(max_extinction, v[i]);
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::size_t c = i % cols;
    if (c < 3) {  // colour
      b.lower.push_back(0);
      b.upper.push_back(1);
      b.scale.push_back(1);
    } else if (c == 3) {  // extinction
      b.lower.push_back(0);
      b.upper.push_back(kInf);
      b.scale.push_back(max_extinction > 0 ? max_extinction : 1.0);
    } else {  // Gaussian mean (free) and width (> 0)
      b.lower.push_back(c == 4 ? -kInf : 1e-6 * density_scale);
      b.upper.push_back(kInf);
      b.scale.push_back(density_scale);
    }
  }
  return b;
}

double density_scale(const Scene& scene) {
  const TransferFunction& tf = scene.tf;
  double s = 0;
  switch (tf.kind) {
    case TfKind::identity:
      for (float d : scene.volume.data) s = std::max(s, double(d));
      if (!(s > 0)) s = 1;
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
  // Trilinear between cell centres, clamped to the edge centres (DESIGN.md); u in cells of `in`.
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
