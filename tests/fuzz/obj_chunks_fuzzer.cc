// Fuzz target: the OBJ reader's chunked, parallel parsing against one chunk on one thread
// (engine/scene/obj_reader.h promises the objects, ids, errors and their lines of a sequential read
// whatever the thread count or chunk size). Byte 0 picks the chunk size (1 to 97 bytes: many chunk
// boundaries in a small file), byte 1 the parsing threads (0 to 2); the rest is the OBJ file. Any
// difference aborts: a silent wrong answer of the parallel reader.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "engine/scene/obj_reader.h"
#include "fuzz_util.h"

namespace {

struct Read {
  std::vector<mktree::SceneObject> objects;
  std::string error;  // the Status that ended the read (open or Next), empty when none
};

Read ReadAll(const std::string& path, const mktree::ObjReadOptions& options) {
  Read r;
  auto source = mktree::OpenObjFile(path, 0, options);
  if (!source.ok()) {
    r.error = "open: " + source.status().ToString();
    return r;
  }
  for (;;) {
    mktree::SceneObject obj;
    auto more = (*source)->Next(&obj);
    if (!more.ok()) {
      r.error = more.status().ToString();
      return r;
    }
    if (!*more) return r;
    for (uint32_t t : obj.mesh.triangles)
      if (t >= obj.mesh.vertex_count()) std::abort();  // a mesh that indexes outside itself
    r.objects.push_back(std::move(obj));
  }
}

bool Same(const mktree::SceneObject& x, const mktree::SceneObject& y) {
  return x.id == y.id && x.name == y.name && x.source == y.source && x.attributes == y.attributes &&
         x.mesh.triangles == y.mesh.triangles && x.mesh.vertices.size() == y.mesh.vertices.size() &&
         std::memcmp(x.mesh.vertices.data(), y.mesh.vertices.data(), 8 * x.mesh.vertices.size()) == 0;
}

[[noreturn]] void Differ(const char* what, const Read& one, const Read& chunked) {
  std::fprintf(stderr,
               "obj_chunks: %s differs: one chunk %zu objects, error '%s'; chunked %zu objects, error '%s'\n",
               what, one.objects.size(), one.error.c_str(), chunked.objects.size(), chunked.error.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  mktree::ObjReadOptions chunked;
  chunked.chunk_bytes = 1 + data[0] % 97;
  chunked.threads = data[1] % 3;
  mktree::ObjReadOptions one;
  one.threads = 0;
  const std::string& path = mktree::fuzz::InputFile::Get().Write(data + 2, size - 2);
  const Read a = ReadAll(path, one);
  const Read b = ReadAll(path, chunked);
  if (a.error != b.error) Differ("the error", a, b);
  if (a.objects.size() != b.objects.size()) Differ("the object count", a, b);
  for (size_t i = 0; i < a.objects.size(); ++i)
    if (!Same(a.objects[i], b.objects[i])) Differ("an object", a, b);
  if (!a.error.empty()) {
    mktree::fuzz::Refused(a.error);
    return 0;
  }
  ++mktree::fuzz::g_accepted;
  return 0;
}
