// reconstruct_checkpoint.cpp — a reconstruction's checkpoint: PREFIX_checkpoint.json (iteration,
// level, options' fingerprint, TF and optimiser state, history; doubles round-trip exactly) and
// PREFIX_checkpoint_{density,first,second}.npy (float64). Resuming restores every bit.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "files.hpp"
#include "ivr/error.hpp"
#include "ivr/volume_io.hpp"
#include "optimizer.hpp"
#include "real_args.hpp"
#include "reconstruct_impl.hpp"

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
  return {{"density", o.density},
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
    const std::string names[3] = {prefix + "_checkpoint_density.npy",
                                  prefix + "_checkpoint_first.npy",
                                  prefix + "_checkpoint_second.npy"};
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
}

void Reconstruction::remove_checkpoint(const std::string& prefix) {
  for (const char* suffix : {"_checkpoint.json", "_checkpoint_density.npy", "_checkpoint_first.npy",
                             "_checkpoint_second.npy"})
    std::remove((prefix + suffix).c_str());  // a file that is not there is fine
}

void Reconstruction::resume(const std::string& prefix) {
  Impl& p = *impl_;
  const std::string path = prefix + "_checkpoint.json";
  const std::string dir = parent_dir(path);
  json j;
  try {
    j = json::parse(read_text_file(path, "checkpoint"));
  } catch (const json::exception& e) {
    throw Error(Status::invalid_argument, "resume: '" + path + "' is not JSON: " + e.what());
  }
  try {
    if (j.value("format", "") != kFormat || j.value("version", 0) != 1)
      throw Error(Status::invalid_argument, "resume: '" + path +
                                                "' is not a version-1 ivr "
                                                "reconstruct checkpoint");
    const json mine = fingerprint(p), theirs = j.at("fingerprint");
    for (auto it = mine.begin(); it != mine.end(); ++it)
      if (!theirs.contains(it.key()) || theirs[it.key()] != it.value())
        throw Error(Status::invalid_argument,
                    "resume: the checkpoint '" + path + "' was written with " + it.key() + " = " +
                        (theirs.contains(it.key()) ? theirs[it.key()].dump() : "nothing") +
                        ", this run has " + it.value().dump());
    const int k = j.at("iteration").get<int>();
    const int level = j.at("level").get<int>();
    if (k < 0 || k > p.o.iterations || (p.o.density && level != p.level_of(k == 0 ? 0 : k - 1)))
      throw Error(Status::invalid_argument, "resume: '" + path + "' has iteration " +
                                                std::to_string(k) + " on level " +
                                                std::to_string(level) + ", which this run lacks");
    if (p.o.density) {
      const json& d = j.at("density");
      const std::vector<int>& dims = p.dims[std::size_t(level)];
      const std::size_t n = std::size_t(dims[0]) * dims[1] * dims[2];
      p.enter_level(level, read_array(dir + "/" + d.at("values").get<std::string>(), n));
      Optimizer::State s;
      s.iterations = d.at("iterations").get<int>();
      s.first = read_array(dir + "/" + d.at("first").get<std::string>(), n);
      if (!d.at("second").is_null())
        s.second = read_array(dir + "/" + d.at("second").get<std::string>(), n);
      p.density_opt->restore(s);
      // (Checkpoints of earlier versions also hold "fixed_exponent", the deterministic
      // gradient's carried scale; the scale is now a function of each gradient's inputs.)
    }
    if (p.o.tf) {
      const json& tf = j.at("tf");
      p.u = tf.at("u").get<std::vector<double>>();
      if (p.tf_opt) p.tf_opt->restore(optimizer_state(tf.at("optimizer")));
      if (p.lbfgs) {
        const json& l = tf.at("lbfgs");
        Lbfgs::State s;
        s.iterations = l.at("iterations").get<int>();
        s.evaluated = l.at("evaluated").get<bool>();
        s.f = number(l.at("f"));
        s.g = l.at("g").get<std::vector<double>>();
        s.s = l.at("s").get<std::vector<std::vector<double>>>();
        s.y = l.at("y").get<std::vector<std::vector<double>>>();
        p.lbfgs->restore(s);
      }
      p.apply_tf();
    }
    p.history.clear();
    for (const json& r : j.at("history")) {
      IterationRecord rec;
      rec.iteration = r.at(0).get<int>();
      rec.level = r.at(1).get<int>();
      rec.loss = number(r.at(2));
      rec.prior = number(r.at(3));
      rec.lr = r.at(4).get<double>();
      rec.seconds = r.at(5).get<double>();
      rec.views = r.at(6).get<int>();
      p.history.push_back(rec);
    }
    p.k = k;
  } catch (const json::exception& e) {
    throw Error(Status::invalid_argument, "resume: '" + path + "' is damaged: " + e.what());
  }
}

}  // namespace ivr
