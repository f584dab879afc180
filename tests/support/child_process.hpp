#pragma once
// A real binary started as a child of the test, its stdout and stderr to a file: for tests that
// signal it, wait for it, or read its resource use from the kernel.
#include <fcntl.h>
#include <sys/types.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

namespace inertia::testing {

/// Starts args[0] with `args`, its output to `output`; returns its pid.
inline pid_t start_child(const std::vector<std::string>& args, const std::filesystem::path& output) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(output.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  return pid;
}

}  // namespace inertia::testing
