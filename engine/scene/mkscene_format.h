// The .mks binary scene format: a compact, checksummed, streamable file of scene objects, for scenes too
// large for OBJ.
//
// Why a binary format: OBJ face indices are global to the file, so a streaming OBJ reader must keep every
// vertex it has read (gigabytes at 10 M objects) to resolve the indices of later faces; and it spends most
// of its time parsing decimal text. An .mks object record is self-contained (its triangles index its own
// vertices), so the reader keeps exactly one object in memory, copies float64 and uint32 arrays without
// parsing, and verifies each record with a checksum, so a damaged file is refused with the object and byte
// offset that is wrong instead of producing a silently wrong scene. Vertices are float64, so coordinates
// far from 0 (UTM, geocentric) keep their precision.
//
// Layout (all integers and floats little-endian):
//   header   : magic "MKSCENE\0" (8 bytes), u32 version (= 2), u32 flags (= 0)
//   object   : u32 tag "MKOB", u32 name_bytes, name (UTF-8, no terminator), u32 vertex_count,
//              u32 triangle_count, f64 vertices[3 * vertex_count], u32 triangles[3 * triangle_count],
//              u64 XXH3-64 (seed 0) of every preceding byte of this record, from the tag on
//   ... one record per object, in id order ...
//   end      : u32 tag "MKEN", u32 reserved (= 0), u64 object_count, u64 XXH3-64 of the 16 bytes before it
//   Nothing may follow the end record. Triangle indices are < vertex_count; vertices are finite.
//
// Ids are not stored: as for every scene file, object k of the file gets id first_id + k.
// Version 1 files (f32 vertices, otherwise the same) are still read.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "engine/scene/scene_source.h"
#include "storage/atomic_file.h"

namespace mktree {

// Opens an .mks file for streaming; the k-th object gets id first_id + k. Fails (naming the file) when it
// cannot be opened or its header is wrong (bad magic, unsupported version). Next() fails with Corruption
// naming the file, the object index and the byte offset on a checksum mismatch, a truncated record, a
// missing or inconsistent end record, or trailing bytes. Memory: one object plus a fixed read buffer.
// Thread-safety: a source is used by one thread at a time.
Result<std::unique_ptr<SceneSource>> OpenMkSceneFile(const std::string& path, ObjectId first_id = 0);

// Streams objects into an .mks file. The file is an AtomicFile (storage/atomic_file.h): written as
// `<path>.tmp.<pid>`, which Finish() makes durable and renames onto `path`, so an interrupted run leaves no
// partial scene; the destructor removes the temporary if Finish() was not reached. Thread-safety: one thread
// at a time.
class MkSceneWriter {
 public:
  static Result<std::unique_ptr<MkSceneWriter>> Create(const std::string& path);
  ~MkSceneWriter();
  MkSceneWriter(const MkSceneWriter&) = delete;
  MkSceneWriter& operator=(const MkSceneWriter&) = delete;

  // Appends one object (its id is implied by its position). REQUIRES: triangle indices < vertex_count,
  // name shorter than 4 GiB (checked: InvalidArgument).
  Status Write(const SceneObject& object);
  // Writes the end record, fsyncs and renames onto `path`. No Write() after it, whatever its outcome.
  Status Finish();

  uint64_t objects_written() const { return objects_; }
  uint64_t bytes_written() const { return bytes_; }

 private:
  MkSceneWriter(std::string path, std::unique_ptr<AtomicFile> file);
  Status Put(const std::vector<uint8_t>& bytes);

  std::string path_;
  std::unique_ptr<AtomicFile> file_;
  bool finished_ = false;
  std::vector<uint8_t> record_;  // the record being encoded; reused
  uint64_t bytes_ = 0;
  uint64_t objects_ = 0;
};

}  // namespace mktree
