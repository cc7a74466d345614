// Makes fuzz seeds from real files (driven by tests/fuzz/make_seeds.sh; not a test):
//   fuzz_seed_tool obj2mks IN.obj OUT.mks          an .mks scene of the OBJ's objects
//   fuzz_seed_tool store_struct STORE OUT          a store_open structured input (mode 2) of STORE
//   fuzz_seed_tool store_raw STORE MODE OUT        a store_open raw input (mode byte MODE, then the file)
//   fuzz_seed_tool leaves STORE OUTDIR MAX         leaf inputs: each leaf's pages (mode 1) and each
//                                                  entry (mode 0) of up to MAX leaves
// STORE may be of either backend: its contents are read through StoreReader and encoded again.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "engine/scene/mkscene_format.h"
#include "engine/scene/obj_reader.h"
#include "engine/store_format/leaf_codec.h"
#include "engine/store_format/store_file.h"
#include "paged_store_image.h"

namespace {

using mktree::Status;

[[noreturn]] void Fail(const std::string& what) {
  std::fprintf(stderr, "fuzz_seed_tool: %s\n", what.c_str());
  std::exit(1);
}
void Check(const Status& st) {
  if (!st.ok()) Fail(st.ToString());
}
void WriteFile(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) Fail(path + ": write failed");
}
std::unique_ptr<mktree::StoreReader> OpenStore(const std::string& path) {
  auto r = mktree::StoreReader::Open(path);
  Check(r.status());
  return std::move(*r);
}
std::vector<uint8_t> Pages(const mktree::StoreReader& r, uint64_t first, uint64_t count) {
  const uint64_t mem_page = r.pages().page_bytes();
  std::vector<uint8_t> out(count * mem_page);
  for (uint64_t i = 0; i < count; ++i) Check(r.pages().ReadPage(first + i, out.data() + i * mem_page));
  return out;
}
void Append(std::vector<uint8_t>* out, const std::vector<uint8_t>& chunk, bool separator) {
  if (std::search(chunk.begin(), chunk.end(), std::begin(mktree::fuzz::kChunkSeparator),
                  std::end(mktree::fuzz::kChunkSeparator)) != chunk.end())
    Fail("a chunk contains the separator");
  if (separator)
    out->insert(out->end(), std::begin(mktree::fuzz::kChunkSeparator),
                std::end(mktree::fuzz::kChunkSeparator));
  out->insert(out->end(), chunk.begin(), chunk.end());
}

int ObjToMks(const std::string& in, const std::string& out) {
  auto src = mktree::OpenObjFile(in);
  Check(src.status());
  auto w = mktree::MkSceneWriter::Create(out);
  Check(w.status());
  mktree::SceneObject obj;
  for (;;) {
    auto more = (*src)->Next(&obj);
    Check(more.status());
    if (!*more) break;
    Check((*w)->Write(obj));
  }
  Check((*w)->Finish());
  return 0;
}

int StoreStruct(const std::string& store, const std::string& out_path) {
  auto r = OpenStore(store);
  const mktree::MKTree& t = r->tree();
  const mktree::ObjectTable& o = r->objects();
  std::vector<uint8_t> out{2};  // mode 2: structured
  const std::vector<uint8_t> params = mktree::EncodeParams(r->options().params, r->options().codec);
  out.insert(out.end(), params.begin(), params.end());
  Append(&out, Pages(*r, 0, r->pages().page_count()), false);
  Append(&out, mktree::EncodeNodes(t.nodes), true);
  Append(&out, mktree::EncodeSplitNodes(t.split_nodes), true);
  Append(&out, mktree::EncodeLeaves(t.leaves), true);
  Append(&out, mktree::EncodeLeafDigests(o), true);
  Append(&out, mktree::EncodeRecordDirectory(o.record_directory), true);
  Append(&out, mktree::EncodeSources(o.sources), true);
  Append(&out, std::vector<uint8_t>(r->stats_json().begin(), r->stats_json().end()), true);
  Append(&out, t.leaf_filter, true);
  const auto& dictionary = r->options().codec.dictionary;
  Append(&out, dictionary ? dictionary->bytes() : std::vector<uint8_t>(), true);
  WriteFile(out_path, out);
  return 0;
}

int StoreRaw(const std::string& store, int mode, const std::string& out_path) {
  std::ifstream in(store, std::ios::binary);
  std::vector<uint8_t> out{static_cast<uint8_t>(mode)};
  out.insert(out.end(), std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  WriteFile(out_path, out);
  return 0;
}

int Leaves(const std::string& store, const std::string& dir, size_t max_leaves) {
  auto r = OpenStore(store);
  const uint64_t mem_page = r->pages().page_bytes();
  int code = -1;
  for (int c = 0; c < 4; ++c)
    if ((uint64_t{512} << c) == mem_page) code = c;
  if (code < 0) Fail("leaf seeds need a page of 512, 1024, 2048 or 4096 bytes");
  const auto& leaves = r->tree().leaves;
  for (size_t l = 0; l < leaves.size() && l < max_leaves; ++l) {
    std::vector<uint8_t> pages = Pages(*r, leaves[l].first_page, leaves[l].page_count);
    std::vector<uint8_t> seed{1, static_cast<uint8_t>(code)};
    seed.insert(seed.end(), pages.begin(), pages.end());
    WriteFile(dir + "/leaf" + std::to_string(l) + "-pages", seed);
    std::vector<const uint8_t*> page_ptrs;
    for (uint32_t i = 0; i < leaves[l].page_count; ++i) page_ptrs.push_back(pages.data() + i * mem_page);
    auto view = mktree::LeafView::Parse(store, static_cast<uint32_t>(l), leaves[l].first_page, page_ptrs,
                                        mem_page, true);
    Check(view.status());
    for (size_t e = 0; e < view->size() && e < 4; ++e) {
      const mktree::ObjectEntryView& v = view->entry(e);
      const uint8_t* begin = v.geometry.data() - mktree::kObjectEntryHeaderBytes;
      std::vector<uint8_t> entry{0, 0};
      entry.insert(entry.end(), begin, begin + v.entry_bytes());
      WriteFile(dir + "/leaf" + std::to_string(l) + "-entry" + std::to_string(e), entry);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> a(argv + 1, argv + argc);
  if (a.size() == 3 && a[0] == "obj2mks") return ObjToMks(a[1], a[2]);
  if (a.size() == 3 && a[0] == "store_struct") return StoreStruct(a[1], a[2]);
  if (a.size() == 4 && a[0] == "store_raw") return StoreRaw(a[1], std::atoi(a[2].c_str()), a[3]);
  if (a.size() == 4 && a[0] == "leaves") return Leaves(a[1], a[2], std::strtoull(a[3].c_str(), nullptr, 10));
  Fail("usage: see tests/fuzz/seed_tool.cc");
}
