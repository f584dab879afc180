// inertia-analyze: one binary, several verbs (design.md, "Command line").
// Exit status: 0 success, 2 bad input (InputError, CLI misuse), 1 anything else.
#include <CLI/CLI.hpp>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>

#include "common/input_error.hpp"
#include "hal/sim/simulate.hpp"

namespace {

int run(int argc, char** argv) {
  CLI::App app{"inertia-analyze: identify nonlinear dynamic models of inertial sensors"};
  app.require_subcommand(1);

  std::filesystem::path bench_path, out_dir;
  auto* simulate = app.add_subcommand("simulate", "simulate a bench's test plan into a dataset folder");
  simulate->add_option("--bench", bench_path, "bench configuration (TOML)")->required();
  simulate->add_option("--out", out_dir, "dataset folder to write")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? inertia::kExitOk : inertia::kExitBadInput;
  }

  if (simulate->parsed()) return inertia::sim::run_simulate(bench_path, out_dir, std::cout);
  return inertia::kExitBadInput;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const inertia::InputError& e) {
    std::cerr << "inertia-analyze: " << e.what() << '\n';
    return inertia::kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "inertia-analyze: error: " << e.what() << '\n';
    return inertia::kExitFailure;
  }
}
