// mktree info STORE [--json] [--object ID] [--revision R]: what a store holds at a revision and how its
// base's tree is shaped, or one object's record. The JSON keys are documented in docs/cli.md.
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>

#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/json_text.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

struct InfoArgs {
  std::string store;
  bool json = false;
  bool has_object = false;
  uint64_t object = 0;
  uint64_t revision = 0;
  bool has_revision = false;
};

OpenOptions InfoOpenOptions(const InfoArgs& a, uint64_t cache_pages) {
  OpenOptions o;
  o.cache_pages = cache_pages;
  if (a.has_revision) o.revision = a.revision;
  return o;
}

// The revision info describes (mktree/changes.h): its number and live objects, the base store whose tree
// the rest of info describes, and what lies beside that base.
struct RevisionView {
  std::unique_ptr<Database> db;  // holds the revision while info reads its base
  std::string base_path;         // the store file itself for a store that has taken no change
  uint64_t deltas = 0, delta_objects = 0, removed = 0;
};

Result<RevisionView> OpenRevisionView(const InfoArgs& a) {
  RevisionView v;
  MKTREE_ASSIGN_OR_RETURN(v.db, Database::Open(a.store, InfoOpenOptions(a, 0)));
  MKTREE_ASSIGN_OR_RETURN(StoreRevision r, OpenStoreRevision(a.store, v.db->revision()));
  v.base_path = a.store;
  if (!r.hold) return v;
  const RevisionManifest& m = r.hold->manifest();
  v.base_path = ChangesFile(ChangesFolder(a.store), m.base.store.name);
  v.deltas = m.deltas.size();
  for (const RevisionPart& d : m.deltas) v.delta_objects += d.objects;
  for (const RevisionIdList& l : m.removals) v.removed += l.count;
  return v;
}

std::string Real(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// "[[x0, y0, z0], [x1, y1, z1]]", or null for an empty box.
std::string JsonBox(const Box3d& b) {
  if (b.empty()) return "null";
  return "[[" + Real(b.min[0]) + ", " + Real(b.min[1]) + ", " + Real(b.min[2]) + "], [" + Real(b.max[0]) +
         ", " + Real(b.max[1]) + ", " + Real(b.max[2]) + "]]";
}
std::string TextBox(const Box3d& b) {
  if (b.empty()) return "empty";
  char buf[256];
  std::snprintf(buf, sizeof buf, "(%.10g, %.10g, %.10g) - (%.10g, %.10g, %.10g)", b.min[0], b.min[1],
                b.min[2], b.max[0], b.max[1], b.max[2]);
  return buf;
}

// One object's record (Database::Object): name, source, attributes, box in world coordinates.
int RunObject(const InfoArgs& a) {
  auto db = Database::Open(a.store, InfoOpenOptions(a, 16));
  if (!db.ok()) return Fail(db.status().message());
  if (a.object >= (*db)->id_limit())
    return Fail(a.store + ": --object " + std::to_string(a.object) + " out of range (" +
                std::to_string((*db)->id_limit()) + " object ids at revision " +
                std::to_string((*db)->revision()) + ")");
  auto r = (*db)->Object(static_cast<ObjectId>(a.object));
  if (!r.ok()) return Fail(r.status().message());
  std::string out;
  if (a.json) {
    out = "{\"id\": " + std::to_string(r->id) + ", \"name\": \"" + JsonText(r->name) + "\", \"source\": \"" +
          JsonText(r->source) + "\", \"box\": " + JsonBox(r->box) + ", \"attributes\": [";
    for (size_t i = 0; i < r->attributes.size(); ++i) {
      if (i) out += ", ";
      out += "{\"key\": \"" + JsonText(r->attributes[i].key) + "\", \"value\": \"" +
             JsonText(r->attributes[i].value) + "\"}";
    }
    out += "]}\n";
  } else {
    out = "object       " + std::to_string(r->id) + "\nname         " + LineText(r->name) +
          "\nsource       " + (r->source.empty() ? std::string("(none)") : LineText(r->source)) +
          "\nbox          " + TextBox(r->box) + " (world)\nattributes   " +
          std::to_string(r->attributes.size()) + "\n";
    for (const ObjectAttribute& at : r->attributes)
      out += "  " + LineText(at.key) + " = " + LineText(at.value) + "\n";
  }
  if (std::fwrite(out.data(), 1, out.size(), stdout) != out.size() || std::fflush(stdout) != 0)
    return Fail("cannot write to standard output");
  return 0;
}

// A sharded store (docs/shards.md) at a revision: its base manifest's top levels and shards, after opening
// the revision whole (every shard store and id file checked), and what lies beside that base.
int RunManifestInfo(const InfoArgs& a) {
  auto view = OpenRevisionView(a);
  if (!view.ok()) return Fail(view.status().message());
  const RevisionView& v = *view;
  auto m = ReadManifest(v.base_path);
  if (!m.ok()) return Fail(m.status().message());
  const auto live = static_cast<unsigned long long>(v.db->object_count());
  const auto revision = static_cast<unsigned long long>(v.db->revision());
  const char* keys[] = {"min", "max"};
  if (a.json) {
    std::string top = "[", shards = "[";
    for (const TopNode& t : m->top.nodes) {
      top += top.size() > 1 ? ", " : "";
      top += t.is_leaf() ? "{\"shard\": " + std::to_string(t.shard) + "}"
                         : "{\"axis\": " + std::to_string(t.axis) + ", \"key\": \"" +
                               keys[static_cast<int>(t.key)] + "\", \"cut\": " + Real(t.cut) + "}";
    }
    for (const ShardEntry& e : m->shards) {
      shards += shards.size() > 1 ? ", " : "";
      shards += "{\"file\": \"" + JsonText(e.store.name) +
                "\", \"file_bytes\": " + std::to_string(e.store.bytes) + ", \"ids_file\": \"" +
                JsonText(e.ids.name) + "\", \"ids_bytes\": " + std::to_string(e.ids.bytes) +
                ", \"objects\": " + std::to_string(e.objects) + "}";
    }
    std::printf(
        "{\"manifest\": \"%s\", \"objects\": %llu, \"revision\": %llu, \"base_objects\": %llu, "
        "\"delta_stores\": %llu, \"delta_objects\": %llu, \"removed_ids\": %llu, \"shards\": %zu, "
        "\"origin\": [%.17g, %.17g, %.17g], "
        "\"bounds\": %s, \"objects_per_page\": %.4f, \"top_levels\": %s], \"shard_files\": %s], \"tree\": "
        "%s}\n",
        JsonText(a.store).c_str(), live, revision, static_cast<unsigned long long>(m->objects),
        static_cast<unsigned long long>(v.deltas), static_cast<unsigned long long>(v.delta_objects),
        static_cast<unsigned long long>(v.removed), m->shards.size(), m->origin.x, m->origin.y, m->origin.z,
        JsonBox(v.db->bounds()).c_str(), v.db->objects_per_page(), top.c_str(), shards.c_str(),
        v.db->stats_json().c_str());
    return 0;
  }
  std::printf("sharded store %s: %llu objects in %zu shards\n", a.store.c_str(), live, m->shards.size());
  std::printf("revision      %llu\n", revision);
  if (v.base_path != a.store)
    std::printf(
        "changes       base %s of %llu objects; %llu delta stores of %llu objects, %llu ids removed\n",
        v.base_path.c_str(), static_cast<unsigned long long>(m->objects),
        static_cast<unsigned long long>(v.deltas), static_cast<unsigned long long>(v.delta_objects),
        static_cast<unsigned long long>(v.removed));
  std::printf("store frame   origin (%.17g, %.17g, %.17g)\n", m->origin.x, m->origin.y, m->origin.z);
  std::printf("bounds        %s (world)\n", TextBox(v.db->bounds()).c_str());
  for (size_t n = 0; n < m->top.nodes.size(); ++n) {
    const TopNode& t = m->top.nodes[n];
    if (t.is_leaf())
      std::printf("top node %zu   shard %u\n", n, t.shard);
    else
      std::printf("top node %zu   box.%s[%c] < %.17g: node %u, else node %u\n", n,
                  keys[static_cast<int>(t.key)], "xyz"[t.axis], t.cut, t.child[0], t.child[1]);
  }
  for (size_t s = 0; s < m->shards.size(); ++s) {
    const ShardEntry& e = m->shards[s];
    std::printf("shard %zu      %s (%s), %llu objects, ids %s\n", s, e.store.name.c_str(),
                HumanBytes(e.store.bytes).c_str(), static_cast<unsigned long long>(e.objects),
                e.ids.name.c_str());
  }
  return 0;
}

int RunInfo(const InfoArgs& a) {
  if (a.has_object) return RunObject(a);
  if (IsManifestFile(a.store)) return RunManifestInfo(a);
  auto view = OpenRevisionView(a);
  if (!view.ok()) return Fail(view.status().message());
  const RevisionView& v = *view;
  const uint64_t live = v.db->object_count(), revision = v.db->revision();
  // Refuses statistics other than the builder's (printed below).
  auto reader = StoreReader::Open(v.base_path);
  if (!reader.ok()) return Fail(reader.status().message());
  const StoreReader& r = **reader;
  const MKTree& t = r.tree();
  struct stat st {};
  const uint64_t file_bytes = ::stat(v.base_path.c_str(), &st) == 0 ? static_cast<uint64_t>(st.st_size) : 0;
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
        "\"revision\": %llu, \"base_objects\": %llu, \"delta_stores\": %llu, \"delta_objects\": %llu, "
        "\"removed_ids\": %llu, "
        "\"nodes\": %zu, \"internal_nodes\": %llu, \"leaves\": %zu, \"pages\": %llu, \"height\": %u, "
        "\"block_size\": %u, \"blocks_per_page\": %u, \"page_bytes\": %llu, \"balance_r\": %g, "
        "\"split_nodes\": %zu, \"split_cells\": %llu, \"split_both_cells\": %llu, \"page_fill\": %.4f, "
        "\"ram_bytes\": %llu, \"leaf_filter_bytes\": %llu, \"origin\": [%.17g, %.17g, %.17g], \"bounds\": "
        "%s, "
        "\"record_pages\": %llu, \"tree\": %s}\n",
        JsonText(a.store).c_str(), static_cast<unsigned long long>(file_bytes), backend, codec,
        static_cast<unsigned long long>(live), static_cast<unsigned long long>(revision),
        static_cast<unsigned long long>(r.object_count()), static_cast<unsigned long long>(v.deltas),
        static_cast<unsigned long long>(v.delta_objects), static_cast<unsigned long long>(v.removed),
        t.nodes.size(), static_cast<unsigned long long>(internal), t.leaves.size(),
        static_cast<unsigned long long>(pages), height, t.params.block_size, t.params.blocks_per_page,
        static_cast<unsigned long long>(mem_page), t.params.balance_r, t.split_nodes.size(),
        static_cast<unsigned long long>(split_cells), static_cast<unsigned long long>(both_cells), fill,
        static_cast<unsigned long long>(t.MemoryBytes()),
        static_cast<unsigned long long>(t.FilterMemoryBytes()), t.origin.x, t.origin.y, t.origin.z,
        JsonBox(t.WorldBounds()).c_str(),
        static_cast<unsigned long long>(r.objects().record_directory.size()),
        r.stats_json().empty() ? "null" : r.stats_json().c_str());
    return 0;
  }
  std::printf("store        %s (%s, %s backend, codec %s)\n", a.store.c_str(), HumanBytes(file_bytes).c_str(),
              backend, codec);
  std::printf("revision     %llu\n", static_cast<unsigned long long>(revision));
  std::printf("objects      %llu live\n", static_cast<unsigned long long>(live));
  if (v.base_path != a.store)
    std::printf("changes      base %s of %llu objects; %llu delta stores of %llu objects, %llu ids removed\n",
                v.base_path.c_str(), static_cast<unsigned long long>(r.object_count()),
                static_cast<unsigned long long>(v.deltas), static_cast<unsigned long long>(v.delta_objects),
                static_cast<unsigned long long>(v.removed));
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
  std::printf("bounds       %s (world)\n", TextBox(t.WorldBounds()).c_str());
  std::printf("records      %llu pages (names, sources, attributes; %zu sources)\n",
              static_cast<unsigned long long>(r.objects().record_directory.size()),
              r.objects().sources.size());
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
  auto* object = AddNumberOption(cmd, "--object", &args->object,
                                 "Print this object's record (name, source, attributes, box)");
  auto* revision = AddNumberOption(cmd, "--revision", &args->revision,
                                   "Describe this kept revision (default: the newest)");
  cmd->callback([run, args, object, revision] {
    args->has_object = object->count() > 0;
    args->has_revision = revision->count() > 0;
    *run = [args] { return RunInfo(*args); };
  });
}

}  // namespace mktree::tools
