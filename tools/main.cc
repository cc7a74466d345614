#include <iostream>

#include "engine/core/guarded.h"
#include "mktree/version.h"
#include "tools/command.h"

namespace mktree::tools {

int Fail(const std::string& message) {
  std::cerr << "error: " << message << "\n";
  return 1;
}

}  // namespace mktree::tools

int main(int argc, char** argv) {
  using namespace mktree::tools;
  CLI::App app{"mktree: an out-of-core 3D spatial database built on Multiresolution Kd-trees"};
  app.set_version_flag("--version", std::string("mktree ") + MKTREE_VERSION_STRING);
  app.require_subcommand(1);
  CommandRun run;
  RegisterGenerate(app, &run);
  RegisterGenerateQueries(app, &run);
  RegisterBuild(app, &run);
  RegisterInfo(app, &run);
  RegisterQuery(app, &run);
  RegisterExport(app, &run), RegisterRender(app, &run);
  RegisterClash(app, &run), RegisterCollide(app, &run);
  RegisterUpdate(app, &run), RegisterLog(app, &run), RegisterCompact(app, &run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() != 0) {
      std::cerr << "error: " << e.what() << "\n";
      return 2;
    }
    return app.exit(e);
  }
  if (!run) return Fail("no subcommand given");
  // The last resort: what a subcommand throws (std::bad_alloc under a memory limit, ...) is one error
  // line and exit code 1, not an abort.
  const std::string context = "mktree " + app.get_subcommands().front()->get_name();
  try {
    return run();
  } catch (...) {
    return Fail(mktree::StatusOfCurrentException(context).message());
  }
}
