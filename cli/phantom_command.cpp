// phantom_command.cpp — `ivr phantom shepp-logan|ellipsoids --size N -o VOL.npy`: writes a
// tomography test volume (ivr/phantom.hpp) as float32 .npy, and as NRRD with --nrrd.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "cli_support.hpp"
#include "commands.hpp"
#include "ivr/core.hpp"

namespace fs = std::filesystem;

namespace ivr::cli {

namespace {

struct PhantomArgs {
  std::string name, output;
  int size = 0;
  std::uint64_t seed = 1;
  int supersample = 1;
  bool nrrd = false;
};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// A hidden name beside `path`, for writing before the final rename.
std::string staging_name(const std::string& path) {
  const fs::path p(path);
  return (p.parent_path() / ("." + p.filename().string() + ".tmp" + std::to_string(::getpid())))
      .string();
}

// An attached NRRD (raw float, host byte order, spacing 1): what 3D Slicer and ParaView open.
void write_nrrd(const std::string& path, const Volume& v, const std::string& comment) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error(Status::io, "cannot write NRRD '" + path + "'");
  const std::uint16_t probe = 1;
  const bool little = *reinterpret_cast<const unsigned char*>(&probe) == 1;
  out << "NRRD0004\n# " << comment << "\ntype: float\ndimension: 3\nsizes: " << v.nx << " " << v.ny
      << " " << v.nz << "\nspacings: 1 1 1\nendian: " << (little ? "little" : "big")
      << "\nencoding: raw\n\n";
  out.write(reinterpret_cast<const char*>(v.data.data()),
            std::streamsize(v.data.size() * sizeof(float)));
  out.close();
  if (!out) throw Error(Status::io, "cannot write NRRD '" + path + "' (disk full?)");
}

}  // namespace

Runner add_phantom_command(CLI::App& app) {
  auto args = std::make_shared<PhantomArgs>();
  CLI::App* cmd = app.add_subcommand(
      "phantom", "Write a tomography test volume: the 3D Shepp-Logan head or random ellipsoids");
  cmd->add_option("name", args->name, "shepp-logan or ellipsoids (10 random ellipsoids)")
      ->required();
  cmd->add_option("--size", args->size, "Voxels along each axis, 1..1024")->required();
  // CLI11 would wrap "-2" or 2^64 into some other seed; name the mistake instead.
  cmd->add_option("--seed", args->seed, "Seed of the random ellipsoids (default 1)")
      ->check([](const std::string& s) {
        const bool digits = !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
        return digits && (s.size() < 20 || (s.size() == 20 && s <= "18446744073709551615"))
                   ? std::string()
                   : "expected an integer in 0..2^64-1, got '" + s + "'";
      });
  cmd->add_option("--supersample", args->supersample,
                  "Each voxel the mean of S³ sub-cell samples (default 1: the voxel centre)")
      ->check(CLI::Range(1, 16));
  cmd->add_option("-o,--output", args->output, "Output .npy: float32 of shape (N, N, N)")
      ->required();
  cmd->add_flag("--nrrd", args->nrrd, "Also write the volume as NRRD beside it (VOL.nrrd)");
  return [args] {
    // Every check before any work or file: a bad call writes nothing.
    const fs::path out(args->output);
    if (lower(out.extension().string()) != ".npy")
      throw input_error("-o: output '" + args->output + "' needs the extension .npy");
    check_output_folder(args->output);
    const std::string nrrd_path = fs::path(out).replace_extension(".nrrd").string();
    Volume v = phantom(args->name, args->size, args->seed, args->supersample);
    const std::size_t n = std::size_t(args->size);

    // The NRRD is staged first and renamed after the .npy, so an error leaves neither behind.
    const std::string staged = args->nrrd ? staging_name(nrrd_path) : "";
    try {
      if (args->nrrd)
        write_nrrd(staged, v,
                   "ivr phantom " + args->name + " --size " + std::to_string(args->size) +
                       (args->name == "ellipsoids" ? " --seed " + std::to_string(args->seed) : ""));
      save_npy(args->output, {n, n, n}, v.data.data());
      if (args->nrrd) {
        std::error_code ec;
        fs::rename(staged, nrrd_path, ec);
        if (ec) {
          const std::string why = ec.message();
          fs::remove(args->output, ec);
          throw Error(Status::io, "cannot write NRRD '" + nrrd_path + "': " + why);
        }
      }
    } catch (...) {
      std::error_code ec;
      if (!staged.empty()) fs::remove(staged, ec);
      throw;
    }
    std::cout << "wrote " << args->name << " phantom " << n << "x" << n << "x" << n << " (float32, "
              << bytes_text(n * n * n * sizeof(float)) << ") -> " << args->output
              << (args->nrrd ? " and " + nrrd_path : "") << "\n";
    return 0;
  };
}

}  // namespace ivr::cli
