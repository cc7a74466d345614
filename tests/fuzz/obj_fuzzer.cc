// Fuzz target: the streaming OBJ reader (engine/scene/obj_reader.h). The input is the file; every object
// is read. The reader must return an error or objects whose triangles index their own vertices.
#include <cstdint>
#include <cstdlib>

#include "engine/scene/obj_reader.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = mktree::fuzz::InputFile::Get().Write(data, size);
  auto source = mktree::OpenObjFile(path, 0);
  if (!source.ok()) {
    mktree::fuzz::Refused(source.status().ToString());
    return 0;
  }
  mktree::SceneObject obj;
  for (;;) {
    auto more = (*source)->Next(&obj);
    if (!more.ok()) {
      mktree::fuzz::Refused(more.status().ToString());
      return 0;
    }
    if (!*more) break;
    const size_t vc = obj.mesh.vertex_count();
    if (obj.mesh.triangles.size() % 3 != 0 || obj.mesh.triangle_count() == 0) std::abort();
    for (uint32_t t : obj.mesh.triangles)
      if (t >= vc) std::abort();  // a mesh that indexes outside itself is a wrong scene
  }
  ++mktree::fuzz::g_accepted;
  return 0;
}
