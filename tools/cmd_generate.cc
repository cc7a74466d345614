// `mktree generate tanker --objects N [--seed S] -o SCENE`: writes the tanker (docs/design.md §12) as
// .obj or .mks (by extension) and prints a one-line summary.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "engine/generator/tanker_generator.h"
#include "engine/scene/mkscene_format.h"
#include "engine/scene/obj_writer.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/path_checks.h"

namespace mktree::tools {
namespace {

struct GenerateOptions {
  std::string kind;
  uint64_t objects = 0;
  uint64_t seed = 1;
  std::string output;
};

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

struct ClassTally {
  uint64_t pipes = 0, plates = 0, equipment = 0;
  void Count(const std::string& name) {
    if (name.starts_with("pipe_"))
      ++pipes;
    else if (name.starts_with("plate_"))
      ++plates;
    else
      ++equipment;
  }
};

// Streams the source into the writer (ObjWriter or MkSceneWriter: same Write/Finish contract).
template <typename Writer>
Result<uint64_t> Stream(SceneSource* source, Writer* writer, ClassTally* tally) {
  SceneObject object;
  while (true) {
    Result<bool> more = source->Next(&object);
    if (!more.ok()) return more.status();
    if (!*more) break;
    tally->Count(object.name);
    MKTREE_RETURN_IF_ERROR(writer->Write(object));
  }
  MKTREE_RETURN_IF_ERROR(writer->Finish());
  return writer->bytes_written();
}

template <typename Writer>
Result<uint64_t> GenerateInto(const std::string& path, SceneSource* source, ClassTally* tally) {
  auto writer = Writer::Create(path);
  if (!writer.ok()) return writer.status();
  return Stream(source, writer->get(), tally);
}

int RunGenerate(const GenerateOptions& opt) {
  if (opt.objects == 0) return Fail("--objects must be at least 1");
  if (opt.objects > (uint64_t{1} << 32))
    return Fail("--objects must be at most 2^32 (object ids are 32-bit)");
  if (Status st = CheckOutputFile(opt.output, {}); !st.ok()) return Fail(st.message());
  const bool obj = EndsWith(opt.output, ".obj"), mks = EndsWith(opt.output, ".mks");
  if (!obj && !mks) return Fail(opt.output + ": unknown scene extension (use .obj or .mks)");

  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<SceneSource> source = MakeTankerSource(opt.objects, opt.seed);
  ClassTally tally;
  Result<uint64_t> bytes = obj ? GenerateInto<ObjWriter>(opt.output, source.get(), &tally)
                               : GenerateInto<MkSceneWriter>(opt.output, source.get(), &tally);
  if (!bytes.ok()) return Fail(bytes.status().ToString());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double total = static_cast<double>(opt.objects);
  char line[512];
  std::snprintf(line, sizeof(line),
                "generated %s: %llu objects (%llu pipes, %llu plates, %llu equipment), seed %llu, %llu bytes "
                "in %.2f s: %.0f objects/s, %.1f MB/s",
                opt.output.c_str(), static_cast<unsigned long long>(opt.objects),
                static_cast<unsigned long long>(tally.pipes), static_cast<unsigned long long>(tally.plates),
                static_cast<unsigned long long>(tally.equipment), static_cast<unsigned long long>(opt.seed),
                static_cast<unsigned long long>(*bytes), seconds, total / seconds,
                static_cast<double>(*bytes) / 1e6 / seconds);
  std::cout << line << std::endl;
  return 0;
}

}  // namespace

void RegisterGenerate(CLI::App& app, CommandRun* run) {
  auto opt = std::make_shared<GenerateOptions>();
  CLI::App* generate = app.add_subcommand("generate", "Generate a synthetic scene or a query file");
  generate->require_subcommand(1);
  CLI::App* cmd =
      generate->add_subcommand("tanker", "The synthetic tanker (docs/design.md §12) as .obj or .mks");
  opt->kind = "tanker";
  AddNumberOption(cmd, "--objects", &opt->objects, "Number of objects N (>= 1)")->required()->default_str("");
  AddNumberOption(cmd, "--seed", &opt->seed, "Random seed: the same seed gives the same file");
  cmd->add_option("-o,--output", opt->output, "Output scene: SCENE.obj or SCENE.mks")->required();
  cmd->callback([opt, run] { *run = [opt] { return RunGenerate(*opt); }; });
}

}  // namespace mktree::tools
