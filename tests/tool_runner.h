// Runs the built `mktree` tool (MKTREE_TOOL) for command-line tests and captures what it printed.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace mktree::testing {

struct ToolRun {
  int code = -1;  // exit code; -1 if the tool did not exit normally
  std::string out, err;
};

inline std::string Slurp(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// `mktree ARGS`, with stdout and stderr captured through two files in `scratch` (removed afterwards).
// `shell_prefix` goes before the command in the shell line (e.g. "ulimit -v 65536; exec ").
inline ToolRun RunMktree(const std::string& args, const std::filesystem::path& scratch,
                         const std::string& shell_prefix = "") {
  const std::filesystem::path out = scratch / "stdout.txt", err = scratch / "stderr.txt";
  const std::string cmd =
      shell_prefix + std::string(MKTREE_TOOL) + " " + args + " >" + out.string() + " 2>" + err.string();
  const int status = std::system(cmd.c_str());
  ToolRun r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = Slurp(out);
  r.err = Slurp(err);
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return r;
}

}  // namespace mktree::testing
