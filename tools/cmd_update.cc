// mktree update STORE [--add SCENE]... [--remove-ids ID,...] [--remove-names FILE] [--replace SCENE]...
// [--message TEXT] [--json]: one batch of changes, committed all or nothing as one new revision
// (mktree/changes.h, docs/cli.md).
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/generator/tanker_spec.h"
#include "engine/scene/scene_source.h"
#include "mktree/changes.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/json_text.h"
#include "tools/path_checks.h"

namespace mktree::tools {

namespace {

struct UpdateArgs {
  std::string store;
  std::vector<std::string> add, replace, remove_ids;
  std::string remove_names;
  bool has_remove_names = false;
  std::string message;
  double compact_threshold = ChangeOptions{}.compact_threshold;
  bool json = false;
};

// Every object of a scene input as `mktree build` reads it (a scene file, or tanker:N[:SEED]), appended to
// *out; the readers' warnings go to stderr as build prints them.
Status ReadSceneInput(const std::string& input, std::vector<SceneObject>* out) {
  std::unique_ptr<SceneSource> source;
  if (IsTankerSpec(input)) {
    const std::optional<TankerSpec> spec = ParseTankerSpec(input);
    if (!spec)
      return Status::InvalidArgument(input +
                                     ": expected tanker:N or tanker:N:SEED in decimal, 1 <= N <= 2^32");
    source = MakeTankerSource(spec->objects, spec->seed);
  } else {
    MKTREE_RETURN_IF_ERROR(CheckInputFile(input));
    MKTREE_ASSIGN_OR_RETURN(source, OpenSceneFile(input));
  }
  SceneObject obj;
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, source->Next(&obj));
    if (!more) break;
    out->push_back(std::move(obj));
    obj = SceneObject();
  }
  for (const std::string& w : source->TakeWarnings()) std::fprintf(stderr, "warning: %s\n", w.c_str());
  return Status::Ok();
}

// "ID,ID,..." (each option value), every field a decimal object id.
Status ParseIds(const std::vector<std::string>& values, std::vector<ObjectId>* out) {
  for (const std::string& v : values) {
    size_t at = 0;
    for (;;) {
      const size_t comma = v.find(',', at);
      const std::string_view field =
          std::string_view(v).substr(at, comma == std::string::npos ? std::string::npos : comma - at);
      const std::optional<ObjectId> id = ParseUnsigned<ObjectId>(field);
      if (!id)
        return Status::InvalidArgument("--remove-ids: '" + std::string(field) +
                                       "' is not an object id (a whole number from 0 to 4294967295)");
      out->push_back(*id);
      if (comma == std::string::npos) break;
      at = comma + 1;
    }
  }
  return Status::Ok();
}

// One name a line (the bytes of the line, without its newline); an empty line is an error naming it.
Status ReadNames(const std::string& path, std::vector<std::string>* out) {
  MKTREE_RETURN_IF_ERROR(CheckInputFile(path));
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IOError(path + ": cannot open");
  std::string line;
  for (uint64_t n = 1; std::getline(in, line); ++n) {
    if (line.empty()) return Status::InvalidArgument(path + ":" + std::to_string(n) + ": an empty name");
    out->push_back(line);
  }
  if (in.bad()) return Status::IOError(path + ": read failed");
  return Status::Ok();
}

Result<ChangeBatch> ReadBatch(const UpdateArgs& a) {
  ChangeBatch batch;
  batch.message = a.message;
  batch.add_files = a.add;  // streamed by the commit, never all in memory
  for (const std::string& in : a.replace) MKTREE_RETURN_IF_ERROR(ReadSceneInput(in, &batch.replace_by_name));
  MKTREE_RETURN_IF_ERROR(ParseIds(a.remove_ids, &batch.remove));
  if (a.has_remove_names) MKTREE_RETURN_IF_ERROR(ReadNames(a.remove_names, &batch.remove_names));
  return batch;
}

int RunUpdate(const UpdateArgs& a) {
  if (!(a.compact_threshold >= 0)) return Fail("--compact-threshold must be >= 0");
  // The replacing scenes are read (and checked) before the store is opened for writing; the added ones
  // are read by the commit, twice (checked and counted, then built), before anything is written.
  auto batch = ReadBatch(a);
  if (!batch.ok()) return Fail(batch.status().message());
  ChangeOptions options;
  options.compact_threshold = a.compact_threshold;
  auto writer = ChangeWriter::Open(a.store, options);
  if (!writer.ok()) return Fail(writer.status().message());
  auto report = (*writer)->Commit(*batch);
  if (!report.ok()) return Fail(report.status().message());
  const CommitReport& r = *report;
  for (const std::string& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (!r.compaction_error.empty()) std::fprintf(stderr, "warning: %s\n", r.compaction_error.c_str());
  std::string out;
  auto u = [](uint64_t v) { return std::to_string(v); };
  if (a.json) {
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%.6f", r.seconds);
    out = "{\"revision\": " + u(r.revision) + ", \"added\": " + u(r.added) +
          ", \"removed\": " + u(r.removed) + ", \"replaced\": " + u(r.replaced) +
          ", \"objects\": " + u(r.objects) + ", \"seconds\": " + seconds +
          ", \"compacted\": " + (r.compacted ? "true" : "false");
    if (!r.added_ids.empty())
      out +=
          ", \"first_added_id\": " + u(r.added_ids.front()) + ", \"last_added_id\": " + u(r.added_ids.back());
    out += "}\n";
  } else {
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%.3f", r.seconds);
    out = "revision " + u(r.revision) + ": " + u(r.added) + " added, " + u(r.removed) + " removed, " +
          u(r.replaced) + " replaced, " + u(r.objects) + " objects" + (r.compacted ? ", compacted" : "") +
          " (" + seconds + " s)\n";
    if (!r.added_ids.empty())
      out += "added ids " + u(r.added_ids.front()) + " to " + u(r.added_ids.back()) + "\n";
  }
  if (std::fwrite(out.data(), 1, out.size(), stdout) != out.size() || std::fflush(stdout) != 0)
    return Fail("cannot write to standard output (revision " + u(r.revision) + " is committed)");
  return 0;
}

}  // namespace

void RegisterUpdate(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<UpdateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "update", "Commit one batch of changes (adds, removes, replaces) to a store as one new revision");
  cmd->add_option("store", args->store, "Store file")->required();
  cmd->add_option("--add", args->add, "Scene whose objects are added (any input build takes; repeatable)");
  cmd->add_option("--remove-ids", args->remove_ids, "Object ids to remove: ID,ID,... (repeatable)");
  auto* names = cmd->add_option("--remove-names", args->remove_names,
                                "File of names, one a line: every live object of each name is removed");
  cmd->add_option("--replace", args->replace,
                  "Scene whose objects each replace the store's one object of the same name, which keeps its "
                  "id (repeatable)");
  cmd->add_option("--message", args->message, "Kept in the revision's log entry");
  AddNumberOption(cmd, "--compact-threshold", &args->compact_threshold,
                  "Compact after the commit once the changes beside the base pass this share of the live "
                  "objects (0: never)");
  cmd->add_flag("--json", args->json, "One JSON line instead of the text summary");
  for (CLI::Option* o :
       {cmd->get_option("--add"), cmd->get_option("--remove-ids"), cmd->get_option("--replace")})
    o->take_all()->allow_extra_args(false)->expected(1)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd->callback([run, args, names] {
    args->has_remove_names = names->count() > 0;
    *run = [args] { return RunUpdate(*args); };
  });
}

}  // namespace mktree::tools
