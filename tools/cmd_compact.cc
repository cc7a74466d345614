// mktree compact STORE [--keep N] [--json]: folds a store's changes into a new base now (docs/cli.md).
#include <cstdio>
#include <string>

#include "mktree/changes.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

struct CompactArgs {
  std::string store;
  uint32_t keep = 0;
  bool has_keep = false;
  bool json = false;
};

int RunCompact(const CompactArgs& a) {
  auto writer = ChangeWriter::Open(a.store);
  if (!writer.ok()) return Fail(writer.status().message());
  if (a.has_keep) {
    if (Status st = (*writer)->SetKeep(a.keep); !st.ok()) return Fail("--keep: " + st.message());
  }
  auto report = (*writer)->Compact();
  if (!report.ok()) return Fail(report.status().message());
  const CompactReport& r = *report;
  auto u = [](uint64_t v) { return std::to_string(v); };
  char seconds[32];
  std::string out;
  if (a.json) {
    std::snprintf(seconds, sizeof seconds, "%.6f", r.seconds);
    out = "{\"revision\": " + u(r.revision) + ", \"objects\": " + u(r.objects) +
          ", \"folded\": " + u(r.folded) + ", \"retired\": " + u(r.retired) +
          ", \"bytes_freed\": " + u(r.bytes_freed) + ", \"seconds\": " + seconds + "}\n";
  } else {
    std::snprintf(seconds, sizeof seconds, "%.3f", r.seconds);
    out = r.folded == 0 ? "nothing to fold: revision " + u(r.revision) + ", " + u(r.objects) + " objects"
                        : "folded " + u(r.folded) + " change lists and stores into revision " +
                              u(r.revision) + ", " + u(r.objects) + " objects";
    out += "; retired " + u(r.retired) + " revisions, freed " + HumanBytes(r.bytes_freed) + " (" + seconds +
           " s)\n";
  }
  if (std::fwrite(out.data(), 1, out.size(), stdout) != out.size() || std::fflush(stdout) != 0)
    return Fail("cannot write to standard output");
  return 0;
}

}  // namespace

void RegisterCompact(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<CompactArgs>();
  CLI::App* cmd = app.add_subcommand("compact", "Fold a store's changes into a new base now");
  cmd->add_option("store", args->store, "Store file")->required();
  auto* keep = AddNumberOption(cmd, "--keep", &args->keep,
                               "Keep the newest N revisions from now on (1 to 1000000; 8 until set)");
  cmd->add_flag("--json", args->json, "One JSON line instead of the text summary");
  cmd->callback([run, args, keep] {
    args->has_keep = keep->count() > 0;
    *run = [args] { return RunCompact(*args); };
  });
}

}  // namespace mktree::tools
