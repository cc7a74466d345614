// mktree generate queries STORE --count N [--seed S] [--sides 0.5,2,8] -o FILE: a seeded query file for
// `mktree query --queries`: N points uniform in the store's bounds, then N boxes of each side centred on
// uniform points. Deterministic: splitmix64, not std distributions, so every platform writes the same file.
#include <cstdio>
#include <filesystem>

#include "storage/store_file.h"
#include "tools/command.h"

namespace mktree::tools {

namespace {

struct QueriesArgs {
  std::string store;
  std::string output;
  uint64_t count = 1000;
  uint64_t seed = 1;
  std::vector<double> sides{0.5, 2, 8};
};

uint64_t SplitMix64(uint64_t* state) {
  uint64_t z = (*state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
double Unit(uint64_t* state) { return static_cast<double>(SplitMix64(state) >> 11) * 0x1.0p-53; }

int RunQueries(const QueriesArgs& a) {
  if (a.count == 0) return Fail("--count must be positive");
  for (double s : a.sides)
    if (!(s > 0)) return Fail("--sides must be positive");
  auto reader = StoreReader::Open(a.store);
  if (!reader.ok()) return Fail(reader.status().message());
  if ((*reader)->tree().empty()) return Fail(a.store + ": empty store");
  const Box3f b = (*reader)->tree().nodes[0].box;
  const std::string tmp = a.output + ".tmp";
  FILE* f = std::fopen(tmp.c_str(), "w");
  if (!f) return Fail(a.output + ": cannot write");
  uint64_t state = a.seed;
  auto point = [&](double c[3]) {
    for (int i = 0; i < 3; ++i) c[i] = b.min[i] + Unit(&state) * (b.max[i] - b.min[i]);
  };
  std::fprintf(f, "# %llu points, then %llu boxes per side; seed %llu; bounds of %s\n",
               static_cast<unsigned long long>(a.count), static_cast<unsigned long long>(a.count),
               static_cast<unsigned long long>(a.seed), a.store.c_str());
  double c[3];
  for (uint64_t i = 0; i < a.count; ++i) {
    point(c);
    std::fprintf(f, "point %.9g %.9g %.9g\n", c[0], c[1], c[2]);
  }
  for (double side : a.sides)
    for (uint64_t i = 0; i < a.count; ++i) {
      point(c);
      std::fprintf(f, "box %.9g %.9g %.9g %.9g %.9g %.9g\n", c[0] - side / 2, c[1] - side / 2, c[2] - side / 2,
                   c[0] + side / 2, c[1] + side / 2, c[2] + side / 2);
    }
  const bool ok = std::ferror(f) == 0;
  if (std::fclose(f) != 0 || !ok) {
    std::filesystem::remove(tmp);
    return Fail(a.output + ": write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, a.output, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    return Fail(a.output + ": " + ec.message());
  }
  return 0;
}

}  // namespace

void RegisterGenerateQueries(CLI::App& app, CommandRun* run) {
  CLI::App* generate = app.get_subcommand("generate");
  auto args = std::make_shared<QueriesArgs>();
  CLI::App* cmd = generate->add_subcommand("queries", "A seeded query file (points and boxes) for a store");
  cmd->add_option("store", args->store, "Store whose bounds the queries fall in")->required();
  cmd->add_option("-o,--output", args->output, "Query file to write")->required();
  cmd->add_option("--count", args->count, "Points, and boxes of each side")->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed")->capture_default_str();
  cmd->add_option("--sides", args->sides, "Box sides")->delimiter(',')->capture_default_str();
  cmd->callback([run, args] { *run = [args] { return RunQueries(*args); }; });
}

}  // namespace mktree::tools
