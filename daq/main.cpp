// inertia-daqd --config FILE [--duration S] [--log DIR] [options]: see daemon.hpp.
// inertia-daqd mark ... / arm ...: the operator's marks, stop and arm to a running daemon (operator_mark.hpp).
#include <iostream>
#include <string>
#include <vector>

#include "common/input_error.hpp"
#include "daq/daemon.hpp"
#include "daq/device_check.hpp"
#include "daq/operator_mark.hpp"

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  try {
    if (!args.empty() && args[0] == "mark") return inertia::daq::run_mark({args.begin() + 1, args.end()});
    if (!args.empty() && args[0] == "arm") return inertia::daq::run_arm({args.begin() + 1, args.end()});
    bool help = false;
    const auto options = inertia::daq::parse_options(args, &help);
    if (help) {
      std::cout << inertia::daq::usage();
      return inertia::kExitOk;
    }
    if (options.check) return inertia::daq::run_device_check(options.config, std::cout);
    return inertia::daq::run_daemon(options);
  } catch (const inertia::InputError& e) {
    std::cerr << "inertia-daqd: " << e.what() << "\n";
    return inertia::kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "inertia-daqd: " << e.what() << "\n";
    return inertia::kExitFailure;
  }
}
