// commands.hpp — the subcommands of the `ivr` tool; each registers itself on the CLI11 app.
#pragma once
#include <CLI/CLI.hpp>
#include <functional>

namespace ivr::cli {

// Adds the subcommand to `app`; the returned function runs it and gives the exit status.
using Runner = std::function<int()>;
Runner add_devices_command(CLI::App& app);
Runner add_render_command(CLI::App& app);
Runner add_gradient_command(CLI::App& app);
Runner add_jacobian_command(CLI::App& app);
Runner add_calibrate_command(CLI::App& app);
Runner add_phantom_command(CLI::App& app);
Runner add_project_command(CLI::App& app);  // tomo_commands.cpp
Runner add_backproject_command(CLI::App& app);
Runner add_tomo_command(CLI::App& app);
Runner add_reconstruct_command(CLI::App& app);  // reconstruct_command.cpp
Runner add_viewpoint_command(CLI::App& app);
Runner add_tune_command(CLI::App& app);

}  // namespace ivr::cli
