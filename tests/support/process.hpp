#pragma once
// Running a shell command from a test: its exit code and its standard output.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace cairn::test {

struct CommandResult {
  int code = -1;  // exit status; -1 when it did not exit normally or could not start
  std::string out;
};

inline CommandResult run_command(const std::string& command) {
  CommandResult r;
  FILE* f = ::popen(command.c_str(), "r");
  if (f == nullptr) return r;
  std::array<char, 4096> buf{};
  for (std::size_t n; (n = std::fread(buf.data(), 1, buf.size(), f)) > 0;) r.out.append(buf.data(), n);
  const int status = ::pclose(f);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace cairn::test
