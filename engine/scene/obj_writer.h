// ObjWriter: streams scene objects into a Wavefront OBJ file.
//
// Output: a comment header, then per object `o NAME`, its `v x y z` lines and its `f a b c` lines.
// Coordinates are printed with std::to_chars (the shortest text that reads back to the same double).
//
// Face indices are negative (relative): -1 is the object's last vertex, -vertex_count its first. Why:
//   - an object's text does not depend on how many vertices came before it, so objects can be formatted
//     independently and the same object always produces the same bytes;
//   - indices stay as short as the object is small (`f -24 -23 -17` rather than 9-digit global indices at
//     10 M objects), about a quarter less text and formatting work at scale;
//   - a reader that notices relative indices could drop vertices of finished objects.
// Relative indices are part of the OBJ specification and read by assimp, Blender, MeshLab, tinyobjloader
// and mktree's own OpenObjFile.
//
// Crash safety: the file is an AtomicFile (storage/atomic_file.h): written as `<path>.tmp.<pid>`, which
// Finish() makes durable and renames onto `path`. A writer destroyed (or a process killed) before Finish()
// leaves no file at `path`: the destructor removes the temporary, and the next writer of `path` removes a
// killed writer's.
//
// Thread-safety: one thread at a time.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mktree/scene.h"
#include "mktree/status.h"
#include "storage/atomic_file.h"

namespace mktree {

class ObjWriter {
 public:
  // Creates the temporary file next to `path`. Fails with IOError naming `path` (e.g. no such directory).
  static Result<std::unique_ptr<ObjWriter>> Create(const std::string& path);
  ~ObjWriter();
  ObjWriter(const ObjWriter&) = delete;
  ObjWriter& operator=(const ObjWriter&) = delete;

  // Appends one object. REQUIRES: every triangle index < vertex_count; the name has no line break
  // (both checked: InvalidArgument). Write errors are IOError naming the file.
  Status Write(const SceneObject& object);
  // Flushes, fsyncs and renames the temporary file onto `path`. No Write() after it, whatever its outcome.
  Status Finish();

  uint64_t objects_written() const { return objects_; }
  uint64_t bytes_written() const { return bytes_ + buffer_.size(); }

 private:
  ObjWriter(std::string path, std::unique_ptr<AtomicFile> file);
  Status Flush();

  std::string path_;
  std::unique_ptr<AtomicFile> file_;
  bool finished_ = false;
  std::vector<char> buffer_;
  uint64_t bytes_ = 0;  // flushed to the file
  uint64_t objects_ = 0;
};

}  // namespace mktree
