// mktree info STORE [--json]: what a store holds and how its tree is shaped. The JSON keys are
// documented in docs/cli.md.
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>

#include "engine/store/store_file.h"
#include "tools/command.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

struct InfoArgs {
  std::string store;
  bool json = false;
};

// A JSON string's contents: quotes and backslashes escaped, control characters as \u00XX.
std::string JsonEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      out += buf;
      continue;
    }
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out;
}

int RunInfo(const InfoArgs& a) {
  auto reader = StoreReader::Open(a.store);  // refuses statistics other than the builder's (printed below)
  if (!reader.ok()) return Fail(reader.status().message());
  const StoreReader& r = **reader;
  const MKTree& t = r.tree();
  struct stat st {};
  const uint64_t file_bytes = ::stat(a.store.c_str(), &st) == 0 ? static_cast<uint64_t>(st.st_size) : 0;
  uint64_t pages = 0, payload = 0, internal = 0, split_cells = 0, both_cells = 0;
  unsigned height = 0;
  for (const LeafInfo& l : t.leaves) {
    pages += l.page_count;
    payload += l.payload_bytes;
  }
  for (const TreeNode& n : t.nodes) {
    internal += !n.is_leaf();
    height = std::max<unsigned>(height, n.depth + 1u);
  }
  for (const SplitNode& s : t.split_nodes) {
    split_cells += s.is_cell();
    both_cells += s.is_cell() && s.label == CellLabel::kBoth;
  }
  const uint64_t mem_page = t.params.mem_page();
  const double fill = pages ? static_cast<double>(payload) / static_cast<double>(pages * mem_page) : 0.0;
  const char* backend = r.options().backend == Backend::kHdf5 ? "hdf5" : "pagefile";
  const char* codec = r.options().codec.codec == Codec::kZstd ? "zstd" : "none";
  if (a.json) {
    std::printf(
        "{\"file\": \"%s\", \"file_bytes\": %llu, \"backend\": \"%s\", \"codec\": \"%s\", \"objects\": %llu, "
        "\"nodes\": %zu, \"internal_nodes\": %llu, \"leaves\": %zu, \"pages\": %llu, \"height\": %u, "
        "\"block_size\": %u, \"blocks_per_page\": %u, \"page_bytes\": %llu, \"balance_r\": %g, "
        "\"split_nodes\": %zu, \"split_cells\": %llu, \"split_both_cells\": %llu, \"page_fill\": %.4f, "
        "\"ram_bytes\": %llu, \"leaf_filter_bytes\": %llu, \"origin\": [%.17g, %.17g, %.17g], \"tree\": "
        "%s}\n",
        JsonEscape(a.store).c_str(), static_cast<unsigned long long>(file_bytes), backend, codec,
        static_cast<unsigned long long>(r.object_count()), t.nodes.size(),
        static_cast<unsigned long long>(internal), t.leaves.size(), static_cast<unsigned long long>(pages),
        height, t.params.block_size, t.params.blocks_per_page, static_cast<unsigned long long>(mem_page),
        t.params.balance_r, t.split_nodes.size(), static_cast<unsigned long long>(split_cells),
        static_cast<unsigned long long>(both_cells), fill, static_cast<unsigned long long>(t.MemoryBytes()),
        static_cast<unsigned long long>(t.FilterMemoryBytes()), t.origin.x, t.origin.y, t.origin.z,
        r.stats_json().empty() ? "null" : r.stats_json().c_str());
    return 0;
  }
  std::printf("store        %s (%s, %s backend, codec %s)\n", a.store.c_str(), HumanBytes(file_bytes).c_str(),
              backend, codec);
  std::printf("objects      %llu\n", static_cast<unsigned long long>(r.object_count()));
  std::printf("nodes        %zu (%llu internal, %zu leaves), height %u\n", t.nodes.size(),
              static_cast<unsigned long long>(internal), t.leaves.size(), height);
  std::printf("pages        %llu of %llu B (%u blocks of %u B), mean fill %.1f%%\n",
              static_cast<unsigned long long>(pages), static_cast<unsigned long long>(mem_page),
              t.params.blocks_per_page, t.params.block_size, 100 * fill);
  std::printf("objects/page %.2f\n",
              pages ? static_cast<double>(r.object_count()) / static_cast<double>(pages) : 0.0);
  std::printf("split trees  %zu nodes, %llu cells, %llu BOTH\n", t.split_nodes.size(),
              static_cast<unsigned long long>(split_cells), static_cast<unsigned long long>(both_cells));
  const double per = r.object_count() ? 1.0 / static_cast<double>(r.object_count()) : 0.0;
  std::printf(
      "RAM          %s for nodes and SplitTrees (%.2f B/object), %s for the leaf filter (%.2f B/object)\n",
      HumanBytes(t.MemoryBytes()).c_str(), static_cast<double>(t.MemoryBytes()) * per,
      HumanBytes(t.FilterMemoryBytes()).c_str(), static_cast<double>(t.FilterMemoryBytes()) * per);
  std::printf("balance r    %g\n", t.params.balance_r);
  std::printf("store frame  origin (%.17g, %.17g, %.17g); geometry is kept relative to it\n", t.origin.x,
              t.origin.y, t.origin.z);
  if (!r.stats_json().empty()) std::printf("builder statistics: %s\n", r.stats_json().c_str());
  return 0;
}

}  // namespace

void RegisterInfo(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<InfoArgs>();
  CLI::App* cmd =
      app.add_subcommand("info", "Describe a store: objects, nodes, leaves, pages, fill, overlap");
  cmd->add_option("store", args->store, "Store file")->required();
  cmd->add_flag("--json", args->json, "One JSON object (keys documented in docs/cli.md)");
  cmd->callback([run, args] { *run = [args] { return RunInfo(*args); }; });
}

}  // namespace mktree::tools
