// Each mktree subcommand registers itself on the CLI11 app; main() runs the chosen one.
// A subcommand's callback returns the process exit code; errors are printed as "error: ..." on stderr.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>

namespace mktree::tools {

// Set by each Register* function: what runs when its subcommand is chosen.
using CommandRun = std::function<int()>;

void RegisterGenerate(CLI::App& app, CommandRun* run);
// Adds `generate queries` under the `generate` subcommand (call after RegisterGenerate).
void RegisterGenerateQueries(CLI::App& app, CommandRun* run);
void RegisterBuild(CLI::App& app, CommandRun* run);
void RegisterInfo(CLI::App& app, CommandRun* run);
void RegisterQuery(CLI::App& app, CommandRun* run);
void RegisterExport(CLI::App& app, CommandRun* run);
void RegisterRender(CLI::App& app, CommandRun* run);
void RegisterClash(CLI::App& app, CommandRun* run);
void RegisterCollide(CLI::App& app, CommandRun* run);
void RegisterUpdate(CLI::App& app, CommandRun* run);
void RegisterLog(CLI::App& app, CommandRun* run);
void RegisterCompact(CLI::App& app, CommandRun* run);

// Prints "error: <message>" to stderr and returns 1.
int Fail(const std::string& message);

}  // namespace mktree::tools
