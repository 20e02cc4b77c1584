// reconstruct.cpp — the reconstruction loop: coarse-to-fine levels, random view batches, the
// gradient (adjoint on the device-resident densities; the planner's mode for the TF alone), the
// priors and the optimisers' steps.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>

#include "ivr/gradient.hpp"
#include "ivr/error.hpp"
#include "multi_device/run_shares.hpp"
#include "reconstruct/optimize.hpp"
#include "runtime/real_args.hpp"
#include "reconstruct/reconstruct.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"
#include "adjoint/adjoint.hpp"
#include "gradient/gradient.hpp"

namespace ivr {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

// splitmix64 (Steele et al. 2014): a portable stream, so batches are the same on every platform.
std::uint64_t splitmix(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// The views of iteration k: a function of (seed, k) only, so a resumed run draws the same.
std::vector<int> batch_views(std::uint64_t seed, int k, int views, int batch) {
  std::vector<int> all(std::size_t(views), 0);
  std::iota(all.begin(), all.end(), 0);
  if (batch <= 0 || batch >= views) return all;
  std::uint64_t state = seed ^ (0xD1B54A32D192ED03ull * std::uint64_t(k + 1));
  for (int i = 0; i < batch; ++i) {
    const int j = i + int(splitmix(state) % std::uint64_t(views - i));
    std::swap(all[std::size_t(i)], all[std::size_t(j)]);
  }
  all.resize(std::size_t(batch));
  std::sort(all.begin(), all.end());
  return all;
}

// tf_smoothness · mean over consecutive rows of Σ_c (u_r,c − u_r−1,c)²; adds its gradient.
double tf_prior(const std::vector<double>& u, std::size_t cols, double weight,
                std::vector<double>& grad) {
  const std::size_t rows = u.size() / cols;
  if (weight == 0 || rows < 2) return 0;
  const double w = weight / double(rows - 1);
  double value = 0;
  for (std::size_t r = 1; r < rows; ++r)
    for (std::size_t c = 0; c < cols; ++c) {
      const double d = u[r * cols + c] - u[(r - 1) * cols + c];
      value += w * d * d;
      grad[r * cols + c] += 2 * w * d;
      grad[(r - 1) * cols + c] -= 2 * w * d;
    }
  return value;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

void validate_reconstruct(const ReconstructOptions& o) {
  if (!o.density && !o.tf) fail("reconstruct: nothing to optimise (density and tf both off)");
  if (o.iterations < 1) fail("iterations must be >= 1, got " + std::to_string(o.iterations));
  if (o.loss == Loss::dot)
    fail("reconstruct: loss dot is a vector-Jacobian product, not a loss to minimise (mse or l1)");
  if (o.batch < 0) fail("batch must be >= 0 (0: every view), got " + std::to_string(o.batch));
  if (o.workers < 1 || o.worker < 0 || o.worker >= o.workers)
    fail("worker " + std::to_string(o.worker) + " of " + std::to_string(o.workers) + " workers");
  if (o.workers > 1 && !o.sum)
    fail(std::to_string(o.workers) + " workers need a sum over the workers");
  if (o.levels < 0 || o.levels > 8)
    fail("levels must be in 0 .. 8 (0: automatic), got " + std::to_string(o.levels));
  const std::pair<const char*, double> weights[] = {
      {"tv", o.tv}, {"smoothness", o.smoothness}, {"tf_smoothness", o.tf_smoothness}};
  for (const auto& [name, value] : weights)
    if (!(value >= 0) || !std::isfinite(value))
      fail(std::string(name) + " must be >= 0 and finite, got " + number_text(value));
  if (!(o.tv_epsilon > 0) || !std::isfinite(o.tv_epsilon))
    fail("tv_epsilon must be > 0 and finite, got " + number_text(o.tv_epsilon));
  if (!(o.init_value >= 0) || !std::isfinite(o.init_value))
    fail("the initial density must be >= 0 and finite, got " + number_text(o.init_value));
  if (!(o.step >= 0) || !std::isfinite(o.step))
    fail("step must be >= 0 and finite, got " + number_text(o.step));
  if (o.optimizer.lr != 0 && (!(o.optimizer.lr > 0) || !std::isfinite(o.optimizer.lr)))
    fail("lr must be > 0 and finite (0: automatic), got " + number_text(o.optimizer.lr));
  OptimizerOptions check = o.optimizer;
  if (check.lr == 0) check.lr = 1;
  if (check.schedule == Schedule::cosine && check.total_iterations < 1)
    check.total_iterations = o.iterations;
  if (check.min_lr > check.lr) check.min_lr = 0;  // checked against the resolved lr later
  validate_optimizer(check);
  if (!o.automatic_optimizer && o.optimizer.kind == OptimizerKind::lbfgs && o.density)
    fail("lbfgs is for small parameter sets (the TF, viewpoints): use adam or sgd for density");
  if (!o.automatic_optimizer && o.optimizer.kind == OptimizerKind::sgd && o.optimizer.lr == 0)
    fail("sgd needs an explicit lr (its steps scale with the gradient's size)");
}

Reconstruction::Impl::Impl(Device& d, const Scene& s, const Image& t, const ReconstructOptions& opt)
    : device(d), dev(d.impl()), scene(s), targets(t), o(opt) {
  validate_reconstruct(o);
  if (o.slabs)
    setup_slabs();  // (the scene holds one slab's planes)
  else
    validate(scene);
  check_target(scene, targets);
  f64 = o.precision == Precision::f64;
  if (f64 && !dev.info.fp64)
    throw Error(Status::unsupported,
                "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
  const int views = image_extent(scene).views;  // a ray list: one "view", every ray
  if (o.workers > 1 && scene.has_ray_list())
    fail("data-parallel reconstruction (" + std::to_string(o.workers) +
         " workers) shares out views: a ray list is one view");
  const int batch = o.batch > 0 ? std::min(o.batch, views) : views;
  if (o.workers > 1 && !o.slabs && batch < o.workers)
    fail("data-parallel reconstruction: batches of " + std::to_string(batch) + " view(s) for " +
         std::to_string(o.workers) + " workers (each needs one)");
  if (o.workers > 1 && !o.slabs && !o.shares.empty())
    for (int w = 0; w < o.workers; ++w)
      if (worker_share(std::size_t(batch), w, o.workers, o.shares).second == 0)
        fail("shares: worker " + std::to_string(w) + "'s share of a batch of " +
             std::to_string(batch) + " views is empty (each needs one): raise its weight");
  if (o.automatic_optimizer)
    o.optimizer.kind = o.density ? OptimizerKind::adam : OptimizerKind::lbfgs;
  if (o.optimizer.kind == OptimizerKind::lbfgs && o.batch > 0 && o.batch < views)
    fail(
        "lbfgs needs every view in every iteration (its line search compares losses): drop "
        "the batch or use adam");
  if (o.optimizer.lr == 0) o.optimizer.lr = o.optimizer.kind == OptimizerKind::lbfgs ? 0.05 : 0.025;
  if (o.optimizer.schedule == Schedule::cosine && o.optimizer.min_lr > o.optimizer.lr)
    fail("min_lr must be in [0, lr], got " + number_text(o.optimizer.min_lr));
  // Over slabs each worker holds one slab: the identity TF's scale is the whole volume's largest
  // density (every worker the same steps as one process), gathered once.
  scale = o.slabs && o.workers > 1 && scene.tf.kind == TfKind::identity
              ? density_scale(scene.tf, slabs_largest_density())
              : density_scale(scene);
  // The TF alone: forward mode while one pass of lanes carries it (<= 32 parameters). Its loss
  // gradient is reduced in a fixed order, where the adjoint's atomic adds are not, so L-BFGS's
  // line searches see one consistent objective and a run repeats (and resumes) bit for bit; it
  // costs about 1.4x the adjoint's time on the default cost model. Beyond that, the planner.
  if (!o.density && o.mode == Mode::automatic && tf_parameters(scene.tf).size() <= 32)
    o.mode = Mode::forward;

  // Levels: each halves the grid, the coarsest at least 4 cells on its shortest axis.
  const Volume& v = scene.volume;
  int count = 1;
  if (o.density) {
    const int shortest = std::min({v.nx, v.ny, v.nz});
    const int wanted = o.levels > 0 ? o.levels : 3;
    while (count < wanted && (shortest >> count) >= 4) ++count;
    count = std::min(count, o.iterations);
    if (o.slabs)  // every worker at least a cell of the coarsest grid along z
      while (count > 1 && ((v.nz + (1 << (count - 1)) - 1) >> (count - 1)) - 1 < o.workers) --count;
  }
  o.levels = count;
  for (int l = 0; l < count; ++l) {
    const int shift = count - 1 - l;
    dims.push_back({(v.nx + (1 << shift) - 1) >> shift, (v.ny + (1 << shift) - 1) >> shift,
                    (v.nz + (1 << shift) - 1) >> shift});
  }
  // Iterations per level in proportion 1 : 2 : 4 … (the finest gets the most).
  const int weight_sum = (1 << count) - 1;
  int done_so_far = 0;
  for (int l = 0; l < count; ++l) {
    const int share = l + 1 == count ? o.iterations - done_so_far
                                     : std::max(1, o.iterations * (1 << l) / weight_sum);
    done_so_far += share;
    level_end.push_back(done_so_far);
  }

  if (o.tf) {
    bounds = tf_bounds(scene.tf, scale);
    const std::vector<double> values = tf_parameters(scene.tf);
    u.resize(values.size());
    for (std::size_t i = 0; i < u.size(); ++i) u[i] = values[i] / bounds.scale[i];
    if (o.optimizer.kind == OptimizerKind::lbfgs) {
      std::vector<double> lo(u.size()), hi(u.size());
      for (std::size_t i = 0; i < u.size(); ++i) {
        lo[i] = bounds.lower[i] / bounds.scale[i];
        hi[i] = bounds.upper[i] / bounds.scale[i];
      }
      lbfgs = std::make_unique<Lbfgs>(lo, hi, o.optimizer.history, o.optimizer.lr);
    } else {
      OptimizerOptions to = o.optimizer;
      if (to.schedule == Schedule::cosine && to.total_iterations < 1)
        to.total_iterations = o.iterations;
      tf_opt = std::make_unique<Optimizer>(device, u.size(), to, o.precision);
    }
  }
  if (!o.density) {  // the TF alone: the scene's volume resident for the whole run
    SessionOptions so;
    so.precision = o.precision;
    so.step = o.step;
    session = std::make_unique<Session>(device, scene, so);
    all_targets = DeviceArray(device, session->image_shape(), f64 ? DType::f64 : DType::f32);
    all_targets.upload(targets.pixels.data(), targets.pixels.size());
  }
  if (o.density) {
    prior = std::make_unique<DensityPrior>(dev, f64);
    std::vector<double> start;
    if (o.init == Init::scene && o.slabs) {
      start.assign(scene.volume.data.begin(), scene.volume.data.end());  // the slab's planes
      if (count > 1)  // (the whole volume gathered once, resampled, this worker's planes kept)
        start = slab_of(resample_volume(gathered(count - 1, start), dims[0][0], dims[0][1],
                                        dims[0][2]));
    } else if (o.init == Init::scene) {
      const Volume coarse = resample_volume(scene.volume, dims[0][0], dims[0][1], dims[0][2]);
      start.assign(coarse.data.begin(), coarse.data.end());
    } else {
      const int planes =
          o.slabs ? domain_slab(dims[0][2], o.worker, o.workers, o.shares).planes() : dims[0][2];
      start.assign(std::size_t(dims[0][0]) * std::size_t(dims[0][1]) * std::size_t(planes),
                   o.init == Init::zeros ? 0.0 : double(float(o.init_value)));
    }
    enter_level(0, start);
  }
}

int Reconstruction::Impl::level_of(int iteration) const {
  int l = 0;
  while (l + 1 < int(level_end.size()) && iteration >= level_end[std::size_t(l)]) ++l;
  return l;
}

OptimizerOptions Reconstruction::Impl::density_optimizer_options(int l) const {
  // Steps in units of the density scale: Adam's lr·scale (ε/scale), SGD's lr·scale².
  OptimizerOptions d = o.optimizer;
  const bool adam = d.kind == OptimizerKind::adam;
  d.lr *= adam ? scale : scale * scale;
  d.min_lr *= adam ? scale : scale * scale;
  if (adam) d.epsilon /= scale;
  d.lower = 0;
  if (d.schedule == Schedule::cosine && d.total_iterations < 1)
    d.total_iterations = level_end[std::size_t(l)] - (l > 0 ? level_end[std::size_t(l - 1)] : 0);
  return d;
}

void Reconstruction::Impl::enter_level(int l, const std::vector<double>& density) {
  Scene grid = scene;
  grid.volume.nx = dims[std::size_t(l)][0];
  grid.volume.ny = dims[std::size_t(l)][1];
  grid.volume.nz = dims[std::size_t(l)][2];
  grid.volume.data.clear();
  if (o.slabs) {  // the slab's densities stay on the host, between the domain gradients
    slab = domain_slab(grid.volume.nz, o.worker, o.workers, o.shares);
    grid.volume.nz = slab.planes();
    level = l;
    level_scene = std::move(grid);
    slab_x = density;
    density_opt = std::make_unique<Optimizer>(device, density.size(),
                                              density_optimizer_options(l), o.precision);
    return;
  }
  SessionOptions so;
  so.precision = o.precision;
  so.step = o.step;
  auto next = std::make_unique<Session>(device, grid, so);
  next->set_volume(density.data(), grid.volume.nz, grid.volume.ny, grid.volume.nx);
  next->integrator();  // a tolerance's step, chosen once per level
  if (!all_targets.valid()) {
    all_targets = DeviceArray(device, next->image_shape(), f64 ? DType::f64 : DType::f32);
    all_targets.upload(targets.pixels.data(), targets.pixels.size());
  }
  level = l;
  level_scene = std::move(grid);
  session = std::move(next);
  density_opt = std::make_unique<Optimizer>(device, density.size(), density_optimizer_options(l),
                                            o.precision);
}

DeviceArray Reconstruction::Impl::batch_targets(const std::vector<int>& views) {
  if (scene.has_ray_list() || int(views.size()) == int(scene.cameras.size())) return all_targets;
  const std::vector<std::int64_t>& shape = all_targets.shape();
  DeviceArray batch(device, {std::int64_t(views.size()), shape[1], shape[2], shape[3]},
                    all_targets.dtype());
  const std::size_t per_view = all_targets.bytes() / scene.cameras.size();
  cl_call("gathering the batch's targets", [&] {
    for (std::size_t i = 0; i < views.size(); ++i)
      dev.queue.enqueueCopyBuffer(buffer_of(all_targets), buffer_of(batch),
                                  std::size_t(views[i]) * per_view, i * per_view, per_view);
  });
  return batch;
}

std::vector<double> Reconstruction::Impl::density_host() const {
  return o.slabs ? slab_x : session->volume().to_doubles();
}

Volume Reconstruction::Impl::level_volume() const {
  Volume v = level_scene.volume;
  const std::vector<double> d = density_host();
  v.data.assign(d.begin(), d.end());
  return v;
}

void Reconstruction::Impl::apply_tf() {
  std::vector<double> values(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) values[i] = u[i] * bounds.scale[i];
  set_tf_parameters(scene.tf, values);
  level_scene.tf = scene.tf;
  if (session) session->set_tf(scene.tf);
}

// The batch this worker shares (its views `views` of the batch's), as the adjoint needs it
// (FixedShare): the batch's size and largest target, and the two collectives built from o.sum.
FixedShare Reconstruction::Impl::batch_share(const std::vector<int>& batch) const {
  FixedShare f;
  const std::size_t per_view = targets.pixels.size() / scene.cameras.size();
  const ImageExtent e = image_extent(scene);
  f.elements = batch.size() * per_view;
  f.rays = batch.size() * std::size_t(e.width) * std::size_t(e.height);
  for (int v : batch)
    for (std::size_t i = 0; i < per_view; ++i)
      f.target_max =
          std::max(f.target_max, double(std::abs(targets.pixels[std::size_t(v) * per_view + i])));
  set_share_collectives(f, o.worker, o.workers, o.sum);
  return f;
}

const IterationRecord& Reconstruction::Impl::step() {
  if (k >= o.iterations)
    fail("the reconstruction is done (" + std::to_string(o.iterations) + " iterations)");
  const auto start = std::chrono::steady_clock::now();
  if (o.density && level_of(k) != level) {
    // (over slabs the coarse grid gathered whole on every worker, each keeping its fine planes)
    const Volume coarse = o.slabs ? gathered(level, slab_x) : level_volume();
    const int l = level_of(k);
    const Volume fine = resample_volume(coarse, dims[std::size_t(l)][0], dims[std::size_t(l)][1],
                                        dims[std::size_t(l)][2]);
    enter_level(l, o.slabs ? slab_of(fine) : std::vector<double>(fine.data.begin(), fine.data.end()));
  }
  std::vector<int> views = batch_views(o.seed, k, image_extent(scene).views, o.batch);
  // Data-parallel: this worker's share of the batch, and its weight in the batch's mean loss: 1
  // for the densities' adjoint, which differentiates the share with the batch's normaliser
  // (FixedShare: its part of the batch's mean, and in fixed point the batch's sums bit for bit);
  // the share's size for the TF's gradient, a mean over the share (the losses are means).
  const std::size_t batch_size = views.size();
  FixedShare share;
  double weight = 1;
  if (o.workers > 1 && !o.slabs) {  // (over slabs every worker marches the whole batch)
    if (o.density) share = batch_share(views);
    const auto [first, count] = worker_share(batch_size, o.worker, o.workers, o.shares);
    views = std::vector<int>(views.begin() + std::ptrdiff_t(first),
                             views.begin() + std::ptrdiff_t(first + count));
    if (!o.density) weight = double(count) / double(batch_size);
  }
  // Σ over the workers of weight × (the loss, then the gradients), every worker getting it.
  auto sum_workers = [&](double& loss, std::vector<std::vector<double>*> grads) {
    if (o.workers <= 1) return;
    std::vector<double> all{weight * loss};
    for (const std::vector<double>* g : grads)
      for (double v : *g) all.push_back(weight * v);
    o.sum(all);
    loss = all[0];
    std::size_t at = 1;
    for (std::vector<double>* g : grads)
      for (double& v : *g) v = all[at++];
  };
  std::vector<Camera> cameras;  // empty for a ray list: the session keeps its rays
  if (!scene.has_ray_list())
    for (int v : views) cameras.push_back(scene.cameras[std::size_t(v)]);
  const std::size_t cols = o.tf ? tf_gradient_shape(scene.tf)[1] : 1;

  IterationRecord r;
  r.iteration = k + 1;
  r.level = o.density ? level : 0;
  r.views = int(batch_size);
  r.lr = learning_rate(o.optimizer, o.density ? density_opt->iterations() : k);
  // The TF's step from its loss gradient (the density's, jointly).
  auto step_tf = [&](const std::vector<double>& tf_grad) {
    std::vector<double> gu(u.size());
    for (std::size_t i = 0; i < u.size(); ++i) gu[i] = tf_grad[i] * bounds.scale[i];
    r.prior += tf_prior(u, cols, o.tf_smoothness, gu);
    tf_opt->step(u, gu);
  };
  if (o.density && o.slabs) {
    std::vector<double> tf_grad;
    std::vector<double> grad = slab_gradient(views, r, tf_grad);
    if (o.tf) step_tf(tf_grad);
    density_opt->step(slab_x, grad);
  } else if (o.density) {
    Session::Impl& s = session->impl();
    if (!cameras.empty()) s.upload_cameras(cameras);
    AdjointRequest request;
    request.density = true;
    request.tf = o.tf;
    request.loss = o.loss;
    request.deterministic = o.deterministic;
    if (o.workers > 1) {
      // Fixed point only where every worker's device sums in it (the collectives must match).
      if (fixed_everywhere < 0) {
        std::vector<double> v{o.deterministic && has_int64_atomics(dev) ? 1.0 : 0.0};
        o.sum(v);
        fixed_everywhere = v[0] == double(o.workers) ? 1 : 0;
      }
      request.deterministic = fixed_everywhere == 1;
      request.share = &share;
    }
    OperationRecord& op = s.begin("gradient");
    AdjointResult gr = enqueue_adjoint(s, batch_targets(views), request, op);
    r.loss = gr.loss.to_doubles()[0];
    r.deterministic = op.stats.deterministic;
    std::vector<double> tf_grad = o.tf ? gr.tf.to_doubles() : std::vector<double>{};
    if (o.workers > 1) {  // the batch's gradient from the workers' parts of it (unweighted)
      if (op.stats.deterministic) {  // (the densities' fixed-point sums are added already)
        sum_workers(r.loss, {&tf_grad});
      } else {
        std::vector<double> density = gr.density.to_doubles();
        sum_workers(r.loss, {&density, &tf_grad});
        gr.density.upload(density.data(), density.size());
      }
    }
    const std::uint64_t real_size = f64 ? 8 : 4, voxels = level_scene.volume.voxel_count();
    r.device_bytes = op.stats.device_bytes +
                     voxels * real_size * (o.optimizer.kind == OptimizerKind::adam ? 2 : 1);
    if (o.tv > 0 || o.smoothness > 0)
      r.prior = prior->add_gradient(level_scene.volume.nx, level_scene.volume.ny,
                                    level_scene.volume.nz, o.tv, o.smoothness, o.tv_epsilon,
                                    buffer_of(s.volume), buffer_of(gr.density));
    if (o.tf) step_tf(tf_grad);
    session->step(*density_opt, gr.density);
  } else {
    // The fixed volume, with this batch's cameras and targets; the TF set per evaluation.
    Session::Impl& s = session->impl();
    if (!cameras.empty()) s.upload_cameras(cameras);
    const DeviceArray batch_target = batch_targets(views);
    GradientRequest request;
    request.wrt = {"tf"};
    request.mode = o.mode;
    request.loss = o.loss;
    auto objective = [&](const std::vector<double>& at, std::vector<double>& grad) {
      std::vector<double> values(at.size());
      for (std::size_t i = 0; i < at.size(); ++i) values[i] = at[i] * bounds.scale[i];
      TransferFunction tf = scene.tf;
      set_tf_parameters(tf, values);
      s.upload_tf(tf);
      const SessionGradient diff = session_gradient(s, batch_target, request);
      std::vector<double> gv = diff.groups.front().second.to_doubles();
      double loss = diff.loss.to_doubles()[0];
      sum_workers(loss, {&gv});
      grad.assign(at.size(), 0.0);
      for (std::size_t i = 0; i < at.size(); ++i) grad[i] = gv[i] * bounds.scale[i];
      const double p = tf_prior(at, cols, o.tf_smoothness, grad);
      r.loss = loss;
      r.prior = p;
      return loss + p;
    };
    if (lbfgs) {
      // The loss reported is the accepted point's (the line search may evaluate several).
      const double f = lbfgs->step(u, objective);
      std::vector<double> unused_grad(u.size(), 0.0);
      r.prior = tf_prior(u, cols, o.tf_smoothness, unused_grad);
      r.loss = f - r.prior;
    } else {
      std::vector<double> gu;
      objective(u, gu);
      tf_opt->step(u, gu);
    }
  }
  if (o.tf) {
    for (std::size_t i = 0; i < u.size(); ++i)
      u[i] = std::clamp(u[i], bounds.lower[i] / bounds.scale[i], bounds.upper[i] / bounds.scale[i]);
    apply_tf();
  }
  if (session) session->finish();
  ++k;
  r.seconds = seconds_since(start);
  history.push_back(r);
  return history.back();
}

Reconstruction::Reconstruction(Device& device, const Scene& scene, const Image& targets,
                               const ReconstructOptions& options)
    : impl_(std::make_unique<Impl>(device, scene, targets, options)) {}
Reconstruction::~Reconstruction() = default;
Reconstruction::Reconstruction(Reconstruction&&) noexcept = default;
Reconstruction& Reconstruction::operator=(Reconstruction&&) noexcept = default;

const IterationRecord& Reconstruction::step() {
  return impl_->step();
}
bool Reconstruction::done() const {
  return impl_->k >= impl_->o.iterations;
}
int Reconstruction::iteration() const {
  return impl_->k;
}
const std::vector<IterationRecord>& Reconstruction::history() const {
  return impl_->history;
}
const ReconstructOptions& Reconstruction::options() const {
  return impl_->o;
}
int Reconstruction::levels() const {
  return int(impl_->dims.size());
}
std::vector<int> Reconstruction::level_dims(int level) const {
  if (level < 0 || level >= levels())
    fail("level " + std::to_string(level) + " of " + std::to_string(levels()));
  return impl_->dims[std::size_t(level)];
}

Scene Reconstruction::result() const {
  const Impl& p = *impl_;
  Scene out = p.scene;
  if (p.o.density && p.o.slabs) {  // this worker's planes of the level's grid (described whole)
    out.volume.nx = p.dims[std::size_t(p.level)][0];
    out.volume.ny = p.dims[std::size_t(p.level)][1];
    out.volume.nz = p.dims[std::size_t(p.level)][2];
    out.volume.data.assign(p.slab_x.begin(), p.slab_x.end());
  } else if (p.o.density) {
    const Volume v = p.level_volume();
    const bool full = v.nx == out.volume.nx && v.ny == out.volume.ny && v.nz == out.volume.nz;
    const glm::dvec3 spacing = out.volume.spacing;
    out.volume = full ? v : resample_volume(v, out.volume.nx, out.volume.ny, out.volume.nz);
    out.volume.spacing = spacing;
  }
  return out;
}

}  // namespace ivr
