// main.cpp — the `ivr` command-line tool: parses the subcommand and turns every error into one
// line on stderr and a non-zero exit status.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>

#include "commands.hpp"
#include "mpi_world.hpp"
#include "ivr/core.hpp"

namespace {
int run(int argc, char** argv);
}

int main(int argc, char** argv) {
  ivr::cli::mpi_begin(&argc, &argv);
  const int status = run(argc, argv);
  // An error in one rank of an mpirun ends them all: the others may be waiting in a collective.
  if (status != 0 && ivr::cli::world().size > 1) ivr::cli::mpi_abort(status);
  ivr::cli::mpi_end();
  return status;
}

namespace {
int run(int argc, char** argv) {
  CLI::App app{"ivr " IVR_VERSION_STRING " — differentiable volume rendering on OpenCL"};
  app.require_subcommand(1);
  app.set_version_flag("--version", IVR_VERSION_STRING);
  const ivr::cli::Runner devices = ivr::cli::add_devices_command(app);
  const ivr::cli::Runner render = ivr::cli::add_render_command(app);
  const ivr::cli::Runner gradient = ivr::cli::add_gradient_command(app);
  const ivr::cli::Runner jacobian = ivr::cli::add_jacobian_command(app);
  const ivr::cli::Runner calibrate = ivr::cli::add_calibrate_command(app);
  const ivr::cli::Runner phantom = ivr::cli::add_phantom_command(app);
  const ivr::cli::Runner project = ivr::cli::add_project_command(app);
  const ivr::cli::Runner backproject = ivr::cli::add_backproject_command(app);
  const ivr::cli::Runner tomo = ivr::cli::add_tomo_command(app);
  const ivr::cli::Runner reconstruct = ivr::cli::add_reconstruct_command(app);
  const ivr::cli::Runner viewpoint = ivr::cli::add_viewpoint_command(app);
  const ivr::cli::Runner tune = ivr::cli::add_tune_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    std::string what = e.what();                     // one line, whatever CLI11 wrote
    std::replace(what.begin(), what.end(), '\n', ' ');
    std::cerr << "ivr: error: " << what << " (see --help)\n";
    return 1;
  }
  try {
    if (app.got_subcommand("devices")) return devices();
    if (app.got_subcommand("render")) return render();
    if (app.got_subcommand("gradient")) return gradient();
    if (app.got_subcommand("jacobian")) return jacobian();
    if (app.got_subcommand("calibrate")) return calibrate();
    if (app.got_subcommand("phantom")) return phantom();
    if (app.got_subcommand("project")) return project();
    if (app.got_subcommand("backproject")) return backproject();
    if (app.got_subcommand("tomo")) return tomo();  // 130 after SIGINT, 143 after SIGTERM
    if (app.got_subcommand("reconstruct")) return reconstruct();  // 130 / 143 likewise
    if (app.got_subcommand("viewpoint")) return viewpoint();
    if (app.got_subcommand("tune")) return tune();
  } catch (const ivr::Error& e) {
    std::cerr << "ivr: error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "ivr: error: out of host memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "ivr: error: " << e.what() << "\n";
    return 1;
  }
  return 1;
}
}  // namespace
