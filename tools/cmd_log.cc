// mktree log STORE [--json]: the revisions a store keeps, oldest first, one a line (docs/cli.md).

#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "mktree/changes.h"
#include "tools/command.h"
#include "tools/json_text.h"

namespace mktree::tools {

namespace {

struct LogArgs {
  std::string store;
  bool json = false;
};

std::string UtcTime(int64_t seconds) {
  const std::time_t t = static_cast<std::time_t>(seconds);
  std::tm tm{};
  if (!gmtime_r(&t, &tm)) return std::to_string(seconds);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
  return buf;
}

std::string LogLine(const RevisionInfo& r, bool json) {
  auto u = [](uint64_t v) { return std::to_string(v); };
  if (json)
    return "{\"revision\": " + u(r.revision) + ", \"time\": " + std::to_string(r.time) +
           ", \"added\": " + u(r.added) + ", \"removed\": " + u(r.removed) +
           ", \"replaced\": " + u(r.replaced) + ", \"objects\": " + u(r.objects) +
           ", \"compaction\": " + (r.compaction ? "true" : "false") + ", \"message\": \"" +
           JsonText(r.message) + "\"}\n";
  return "revision " + u(r.revision) + "  " + UtcTime(r.time) + " UTC  " +
         (r.compaction ? std::string("compaction")
                       : "+" + u(r.added) + " -" + u(r.removed) + " ~" + u(r.replaced)) +
         "  " + u(r.objects) + " objects  " + LineText(r.message) + "\n";
}

int RunLog(const LogArgs& a) {
  auto revisions = ListRevisions(a.store);
  if (!revisions.ok()) return Fail(revisions.status().message());
  std::string out;
  for (const RevisionInfo& r : *revisions) out += LogLine(r, a.json);
  if (std::fwrite(out.data(), 1, out.size(), stdout) != out.size() || std::fflush(stdout) != 0)
    return Fail("cannot write to standard output");
  return 0;
}

}  // namespace

void RegisterLog(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<LogArgs>();
  CLI::App* cmd = app.add_subcommand("log", "The revisions a store keeps, oldest first, one a line");
  cmd->add_option("store", args->store, "Store file")->required();
  cmd->add_flag("--json", args->json, "One JSON object a line (keys documented in docs/cli.md)");
  cmd->callback([run, args] { *run = [args] { return RunLog(*args); }; });
}

}  // namespace mktree::tools
