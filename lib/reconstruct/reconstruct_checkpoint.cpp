// reconstruct_checkpoint.cpp — a reconstruction's checkpoint: PREFIX_checkpoint.json (iteration,
// level, options' fingerprint, TF and optimiser state, history; doubles round-trip exactly) and
// PREFIX_checkpoint_{density,first,second}.npy (float64). Resuming restores every bit.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "io/files.hpp"
#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "ivr/volume_io.hpp"
#include "reconstruct/optimize.hpp"
#include "runtime/real_args.hpp"
#include "reconstruct/reconstruct_checkpoint.hpp"
#include "reconstruct/reconstruct.hpp"

namespace ivr {

namespace {

using json = nlohmann::json;
constexpr const char* kFormat = "ivr reconstruct checkpoint";

std::string base_name(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

// What must match for a checkpoint to continue this run.
json fingerprint(const Reconstruction::Impl& p) {
  const ReconstructOptions& o = p.o;
  const Image& t = p.targets;
  const OptimizerOptions& q = o.optimizer;
  const char* init = o.init == Init::scene ? "scene" : o.init == Init::zeros ? "zeros" : "constant";
  json j = {{"density", o.density},
          {"tf", o.tf},
          {"iterations", o.iterations},
          {"optimizer", optimizer_name(q.kind)},
          {"lr", q.lr},
          {"schedule", schedule_name(q.schedule)},
          {"step_every", q.step_every},
          {"step_gamma", q.step_gamma},
          {"total_iterations", q.total_iterations},
          {"min_lr", q.min_lr},
          {"beta1", q.beta1},
          {"beta2", q.beta2},
          {"epsilon", q.epsilon},
          {"momentum", q.momentum},
          {"history", q.history},
          {"levels", o.levels},
          {"batch", o.batch},
          {"seed", o.seed},
          {"loss", o.loss == Loss::mse ? "mse" : "l1"},
          {"tv", o.tv},
          {"smoothness", o.smoothness},
          {"tf_smoothness", o.tf_smoothness},
          {"tv_epsilon", o.tv_epsilon},
          {"init", init},
          {"init_value", o.init_value},
          {"precision", o.precision == Precision::f64 ? "f64" : "f32"},
          {"step", o.step},
          {"mode", mode_name(o.mode)},
          {"deterministic", o.deterministic},
          {"grid", {p.scene.volume.nx, p.scene.volume.ny, p.scene.volume.nz}},
          {"targets", {t.views, t.height, t.width, t.channels}},
          {"tf_parameters", p.o.tf ? p.u.size() : 0}};
  if (o.slabs) {
    j["slab"] = {o.worker, o.workers};  // each worker's own planes and state
    // Slabs by weight: the worker's planes of the grid where they are not the equal split's
    // (which leaves checkpoints of equal slabs as they were).
    const int nz = p.scene.volume.nz;
    const Slab s = domain_slab(nz, o.worker, o.workers, o.shares);
    const Slab equal = domain_slab(nz, o.worker, o.workers);
    if (s.first != equal.first || s.last != equal.last) j["slab_planes"] = {s.first, s.last};
  }
  return j;
}

// NaN/Inf (a diverged loss) as null: JSON has no such numbers.
json number(double v) {
  return std::isfinite(v) ? json(v) : json(nullptr);
}
double number(const json& j) {
  return j.is_null() ? std::nan("") : j.get<double>();
}

Optimizer::State optimizer_state(const json& j) {
  Optimizer::State s;
  s.iterations = j.at("iterations").get<int>();
  s.first = j.at("first").get<std::vector<double>>();
  s.second = j.at("second").get<std::vector<double>>();
  return s;
}

json optimizer_json(const Optimizer::State& s) {
  return {{"iterations", s.iterations}, {"first", s.first}, {"second", s.second}};
}

std::vector<double> read_array(const std::string& path, std::size_t count) {
  const NpyArray a = load_npy(path);
  if (a.data.size() != count || a.dtype != "float64")
    throw Error(Status::invalid_argument,
                "resume: '" + path + "' holds " + std::to_string(a.data.size()) + " " + a.dtype +
                    " values, expected " + std::to_string(count) + " float64");
  return a.data;
}

// Removes PREFIX_checkpoint_{density,first,second}*.npy but the files named in `keep` (the
// arrays of earlier checkpoints, and of one a killed process did not finish), and the temporary
// files of checkpoint writes a killed process left.
void remove_checkpoint_arrays(const std::string& prefix, const std::vector<std::string>& keep) {
  namespace fs = std::filesystem;
  const std::string dir = parent_dir(prefix + "_checkpoint.json"), base = base_name(prefix);
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    bool ours = false;
    for (const char* part : {"_checkpoint_density", "_checkpoint_first", "_checkpoint_second"})
      ours = ours || name.rfind(base + part, 0) == 0;
    // The temporary file of a checkpoint write that a killed process left (lib/io/files.cpp).
    const bool dead_temporary =
        name.rfind("." + base + "_checkpoint", 0) == 0 && name.find(".tmp") != std::string::npos;
    if ((ours && name.size() > 4 && name.compare(name.size() - 4, 4, ".npy") == 0 &&
         std::find(keep.begin(), keep.end(), name) == keep.end()) ||
        dead_temporary)
      fs::remove(it->path(), ec);
  }
}

}  // namespace

void Reconstruction::save_checkpoint(const std::string& prefix) const {
  const Impl& p = *impl_;
  json j = {{"format", kFormat},
            {"version", 1},
            {"fingerprint", fingerprint(p)},
            {"iteration", p.k},
            {"level", p.level}};
  if (p.o.density) {
    const std::vector<std::size_t> shape = {std::size_t(p.level_scene.volume.nz),
                                            std::size_t(p.level_scene.volume.ny),
                                            std::size_t(p.level_scene.volume.nx)};
    const Optimizer::State s = p.density_opt->state();
    // Named by iteration: the JSON, written last, names the arrays of its own iteration, so a
    // process killed between these writes leaves the previous checkpoint whole.
    const std::string k = "_" + std::to_string(p.k) + ".npy";
    const std::string names[3] = {prefix + "_checkpoint_density" + k,
                                  prefix + "_checkpoint_first" + k,
                                  prefix + "_checkpoint_second" + k};
    save_npy(names[0], shape, p.density_host().data());
    save_npy(names[1], shape, s.first.data());
    if (!s.second.empty()) save_npy(names[2], shape, s.second.data());
    j["density"] = {{"values", base_name(names[0])},
                    {"first", base_name(names[1])},
                    {"second", s.second.empty() ? json(nullptr) : json(base_name(names[2]))},
                    {"iterations", s.iterations}};
  }
  if (p.o.tf) {
    json tf = {{"u", p.u}};
    if (p.tf_opt) tf["optimizer"] = optimizer_json(p.tf_opt->state());
    if (p.lbfgs) {
      const Lbfgs::State& s = p.lbfgs->state();
      tf["lbfgs"] = {{"iterations", s.iterations},
                     {"evaluated", s.evaluated},
                     {"f", number(s.f)},
                     {"g", s.g},
                     {"s", s.s},
                     {"y", s.y}};
    }
    j["tf"] = tf;
  }
  json history = json::array();
  for (const IterationRecord& r : p.history)
    history.push_back(
        {r.iteration, r.level, number(r.loss), number(r.prior), r.lr, r.seconds, r.views});
  j["history"] = history;
  const std::string path = prefix + "_checkpoint.json";
  const std::string text = j.dump(1);
  write_atomically(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::trunc);
    out << text << '\n';
    out.close();
    if (!out) throw Error(Status::io, "cannot write the checkpoint '" + path + "'");
  });
  std::vector<std::string> keep;
  if (p.o.density)
    for (const char* part : {"values", "first", "second"})
      if (j["density"][part].is_string()) keep.push_back(j["density"][part].get<std::string>());
  remove_checkpoint_arrays(prefix, keep);
}

void Reconstruction::remove_checkpoint(const std::string& prefix) {
  std::remove((prefix + "_checkpoint.json").c_str());  // a file that is not there is fine
  remove_checkpoint_arrays(prefix, {});
}

namespace {

void check(bool ok, const std::string& path, const std::string& what) {
  if (!ok) throw Error(Status::invalid_argument, "resume: '" + path + "' " + what);
}

std::vector<double> doubles(const json& j) {
  return j.get<std::vector<double>>();
}

Optimizer::State checked_state(const json& j, std::size_t n, bool second, const std::string& path,
                               const std::string& what) {
  Optimizer::State s = optimizer_state(j);
  check(s.iterations >= 0 && s.first.size() == n && s.second.size() == (second ? n : 0), path,
        "has an optimiser state for " + what + " that does not fit this run");
  return s;
}

}  // namespace

CheckpointData read_checkpoint(const std::string& prefix, const CheckpointShape& shape) {
  const std::string path = prefix + "_checkpoint.json";
  const std::string dir = parent_dir(path);
  json j;
  try {
    j = json::parse(read_text_file(path, "checkpoint"));
  } catch (const json::exception& e) {
    throw Error(Status::invalid_argument, "resume: '" + path + "' is not JSON: " + e.what());
  }
  CheckpointData c;
  try {
    check(j.is_object() && j.value("format", "") == kFormat && j.value("version", 0) == 1, path,
          "is not a version-1 ivr reconstruct checkpoint");
    const json& theirs = j.at("fingerprint");
    check(theirs.is_object(), path, "has no fingerprint object");
    for (auto it = shape.fingerprint.begin(); it != shape.fingerprint.end(); ++it)
      if (!theirs.contains(it.key()) || theirs[it.key()] != it.value())
        throw Error(Status::invalid_argument,
                    "resume: the checkpoint '" + path + "' was written with " + it.key() + " = " +
                        (theirs.contains(it.key()) ? theirs[it.key()].dump() : "nothing") +
                        ", this run has " + it.value().dump());
    if (theirs.contains("slab_planes") && !shape.fingerprint.contains("slab_planes"))
      throw Error(Status::invalid_argument, "resume: the checkpoint '" + path +
                                                "' was written with slab_planes = " +
                                                theirs["slab_planes"].dump() +
                                                ", this run has equal slabs");
    c.iteration = j.at("iteration").get<int>();
    c.level = j.at("level").get<int>();
    const bool density = !shape.voxels.empty();
    const int k = c.iteration;
    check(k >= 0 && k <= shape.iterations &&
              (!density || c.level == shape.level_of(k == 0 ? 0 : k - 1)),
          path, "has iteration " + std::to_string(k) + " on level " + std::to_string(c.level) +
                    ", which this run lacks");
    if (density) {
      const json& d = j.at("density");
      const std::size_t n = shape.voxels.at(std::size_t(c.level));
      // File names only: a checkpoint names files beside itself, nothing elsewhere.
      auto file = [&](const json& name) {
        const std::string f = name.get<std::string>();
        check(!f.empty() && f.find('/') == std::string::npos && f != "." && f != "..", path,
              "names the file '" + f + "', not one beside it");
        return dir + "/" + f;
      };
      c.density = read_array(file(d.at("values")), n);
      c.density_state.iterations = d.at("iterations").get<int>();
      check(c.density_state.iterations >= 0, path, "has a negative optimiser iteration count");
      c.density_state.first = read_array(file(d.at("first")), n);
      check(d.at("second").is_null() != shape.density_second_moments, path,
            "has density second moments where this run's optimiser has none, or none where it "
            "has them");
      if (!d.at("second").is_null()) c.density_state.second = read_array(file(d.at("second")), n);
      // (Checkpoints of earlier versions also hold "fixed_exponent", the deterministic
      // gradient's carried scale; the scale is now a function of each gradient's inputs.)
    }
    if (shape.tf_parameters > 0) {
      const json& tf = j.at("tf");
      const std::size_t n = shape.tf_parameters;
      c.u = doubles(tf.at("u"));
      check(c.u.size() == n, path,
            "has " + std::to_string(c.u.size()) + " TF parameters, this run " + std::to_string(n));
      if (shape.tf_optimizer_second_moments)
        c.tf_state = checked_state(tf.at("optimizer"), n, *shape.tf_optimizer_second_moments, path,
                                   "the TF");
      if (shape.lbfgs_history >= 0) {
        const json& l = tf.at("lbfgs");
        Lbfgs::State s;
        s.iterations = l.at("iterations").get<int>();
        s.evaluated = l.at("evaluated").get<bool>();
        s.f = number(l.at("f"));
        s.g = doubles(l.at("g"));
        s.s = l.at("s").get<std::vector<std::vector<double>>>();
        s.y = l.at("y").get<std::vector<std::vector<double>>>();
        bool fits = s.iterations >= 0 && (s.g.empty() || s.g.size() == n) &&
                    s.s.size() == s.y.size() && s.s.size() <= std::size_t(shape.lbfgs_history);
        for (std::size_t i = 0; fits && i < s.s.size(); ++i)
          fits = s.s[i].size() == n && s.y[i].size() == n;
        check(fits, path, "has an L-BFGS state that does not fit this run");
        c.lbfgs = s;
      }
    }
    for (const json& r : j.at("history")) {
      IterationRecord rec;
      rec.iteration = r.at(0).get<int>();
      rec.level = r.at(1).get<int>();
      rec.loss = number(r.at(2));
      rec.prior = number(r.at(3));
      rec.lr = r.at(4).get<double>();
      rec.seconds = r.at(5).get<double>();
      rec.views = r.at(6).get<int>();
      c.history.push_back(rec);
    }
    check(c.history.size() <= std::size_t(shape.iterations), path,
          "has a longer history than this run's iterations");
  } catch (const json::exception& e) {
    throw Error(Status::invalid_argument, "resume: '" + path + "' is damaged: " + e.what());
  }
  return c;
}

void Reconstruction::resume(const std::string& prefix) {
  Impl& p = *impl_;
  CheckpointShape shape;
  shape.fingerprint = fingerprint(p);
  shape.iterations = p.o.iterations;
  if (p.o.density) {
    shape.level_of = [&p](int i) { return p.level_of(i); };
    for (int l = 0; l < int(p.dims.size()); ++l) shape.voxels.push_back(p.held_voxels(l));
    shape.density_second_moments = p.density_optimizer_options(0).kind == OptimizerKind::adam;
  }
  if (p.o.tf) {
    shape.tf_parameters = p.u.size();
    if (p.tf_opt) shape.tf_optimizer_second_moments = p.o.optimizer.kind == OptimizerKind::adam;
    if (p.lbfgs) shape.lbfgs_history = p.o.optimizer.history;
  }
  // Everything is read and checked before the run changes.
  CheckpointData c = read_checkpoint(prefix, shape);
  if (p.o.density) {
    p.enter_level(c.level, c.density);
    p.density_opt->restore(c.density_state);
  }
  if (p.o.tf) {
    p.u = std::move(c.u);
    if (p.tf_opt) p.tf_opt->restore(*c.tf_state);
    if (p.lbfgs) p.lbfgs->restore(*c.lbfgs);
    p.apply_tf();
  }
  p.history = std::move(c.history);
  p.k = c.iteration;
}

}  // namespace ivr
