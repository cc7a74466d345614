// mktree generate queries STORE --count N [--seed S] [--sides 0.5,2,8] -o FILE: a seeded query file for
// `mktree query --queries`: N points uniform in the store's bounds, then N boxes of each side centred on
// uniform points. Deterministic: splitmix64, not std distributions, so every platform writes the same file.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "engine/store_format/store_file.h"
#include "storage/atomic_file.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/path_checks.h"

namespace mktree::tools {

namespace {

struct QueriesArgs {
  std::string store;
  std::string output;
  uint64_t count = 1000;
  uint64_t seed = 1;
  std::string sides = "0.5,2,8";
};

// "A,B,...": comma-separated finite numbers > 0, at least one.
Result<std::vector<double>> ParseSides(const std::string& text) {
  std::vector<double> sides;
  if (text.empty()) return Status::InvalidArgument("--sides: empty value");
  size_t start = 0;
  while (true) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string field = text.substr(start, comma - start);
    const std::optional<double> side = ParseReal(field);
    if (!side || !std::isfinite(*side) || !(*side > 0))
      return Status::InvalidArgument("--sides: '" + field + "' in '" + text + "' is not a finite number > 0");
    sides.push_back(*side);
    if (comma == text.size()) return sides;
    start = comma + 1;
  }
}

uint64_t SplitMix64(uint64_t* state) {
  uint64_t z = (*state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
double Unit(uint64_t* state) { return static_cast<double>(SplitMix64(state) >> 11) * 0x1.0p-53; }

int RunQueries(const QueriesArgs& a) {
  if (a.count == 0) return Fail("--count must be positive");
  auto sides = ParseSides(a.sides);
  if (!sides.ok()) return Fail(sides.status().message());
  if (Status st = CheckOutputFile(a.output, {a.store}); !st.ok()) return Fail(st.message());
  auto reader = StoreReader::Open(a.store);
  if (!reader.ok()) return Fail(reader.status().message());
  if ((*reader)->tree().empty()) return Fail(a.store + ": empty store");
  const Box3f b = (*reader)->tree().nodes[0].box;
  auto out = AtomicFile::Create(a.output);
  if (!out.ok()) return Fail(out.status().message());
  uint64_t state = a.seed;
  auto point = [&](double c[3]) {
    for (int i = 0; i < 3; ++i) c[i] = b.min[i] + Unit(&state) * (b.max[i] - b.min[i]);
  };
  char line[512];
  auto put = [&](int n) { return (*out)->Write(line, static_cast<size_t>(n)); };
  Status st =
      put(std::snprintf(line, sizeof line, "# %llu points, then %llu boxes per side; seed %llu; bounds of ",
                        static_cast<unsigned long long>(a.count), static_cast<unsigned long long>(a.count),
                        static_cast<unsigned long long>(a.seed)));
  if (st.ok()) st = (*out)->Write(a.store.data(), a.store.size());
  if (st.ok()) st = (*out)->Write("\n", 1);
  double c[3];
  for (uint64_t i = 0; i < a.count && st.ok(); ++i) {
    point(c);
    st = put(std::snprintf(line, sizeof line, "point %.9g %.9g %.9g\n", c[0], c[1], c[2]));
  }
  for (double side : *sides)
    for (uint64_t i = 0; i < a.count && st.ok(); ++i) {
      point(c);
      st = put(std::snprintf(line, sizeof line, "box %.9g %.9g %.9g %.9g %.9g %.9g\n", c[0] - side / 2,
                             c[1] - side / 2, c[2] - side / 2, c[0] + side / 2, c[1] + side / 2,
                             c[2] + side / 2));
    }
  if (st.ok()) st = (*out)->Commit();
  if (!st.ok()) return Fail(st.message());
  return 0;
}

}  // namespace

void RegisterGenerateQueries(CLI::App& app, CommandRun* run) {
  CLI::App* generate = app.get_subcommand("generate");
  auto args = std::make_shared<QueriesArgs>();
  CLI::App* cmd = generate->add_subcommand("queries", "A seeded query file (points and boxes) for a store");
  cmd->add_option("store", args->store, "Store whose bounds the queries fall in")->required();
  cmd->add_option("-o,--output", args->output, "Query file to write")->required();
  AddNumberOption(cmd, "--count", &args->count, "Points, and boxes of each side");
  AddNumberOption(cmd, "--seed", &args->seed, "Seed");
  cmd->add_option("--sides", args->sides, "Box sides: A,B,...")->capture_default_str();
  cmd->callback([run, args] { *run = [args] { return RunQueries(*args); }; });
}

}  // namespace mktree::tools
