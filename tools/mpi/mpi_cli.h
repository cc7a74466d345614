// The command lines of mktree-mpi (tools/mpi): CLI11 as in tools/, on every rank alike, with mktree-mpi's
// own wording of an unknown option and of a number out of range. Errors are printed by rank 0 alone.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>

#include "tools/cli_numbers.h"

namespace mktree {

// Parses argv (argv[0] the command's name) into `app`'s options; returns -1 to go on, else the exit status
// (0 after --help, 2 after a usage error, printed as "error: ..." by rank 0).
inline int ParseMpiCommandLine(CLI::App* app, int argc, char** argv, int rank) {
  app->allow_extras();
  try {
    app->parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) {
      if (rank == 0) app->exit(e);
      return 0;
    }
    if (rank == 0) std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  for (const std::string& extra : app->remaining()) {
    if (rank == 0) std::fprintf(stderr, "error: unknown option %s\n", extra.c_str());
    return 2;
  }
  return -1;
}

// A count option given as text: decimal digits, from 0 (or 1 when `positive`) to `most`.
inline std::optional<uint64_t> CountOption(const std::string& text, uint64_t most, bool positive = false) {
  const std::optional<uint64_t> n = tools::ParseUnsigned<uint64_t>(text);
  if (!n || *n > most || (positive && *n == 0)) return std::nullopt;
  return n;
}

// Prints "error: <message>" on rank 0 and returns 2 (a usage error).
inline int UsageError(int rank, const std::string& message) {
  if (rank == 0) std::fprintf(stderr, "error: %s\n", message.c_str());
  return 2;
}

}  // namespace mktree
