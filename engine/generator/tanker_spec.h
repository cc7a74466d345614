// The generator as a build input: "tanker:N" or "tanker:N:SEED" (docs/cli.md), read by `mktree build` and
// mktree-mpi alike.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace mktree {

struct TankerSpec {
  uint64_t objects = 0;
  uint64_t seed = 1;
};

// Whether `input` names the generator (starts with "tanker:"), well formed or not.
bool IsTankerSpec(std::string_view input);
// N and SEED in decimal (digits only), 1 <= N <= 2^32, SEED 1 when left out; nullopt for anything else.
std::optional<TankerSpec> ParseTankerSpec(std::string_view input);

}  // namespace mktree
