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

// Reading an .mks file in byte ranges, each by its own process (mktree-mpi): a part holds the records whose
// first byte lies in its range. FindMkScenePart finds the first by resync (the tag "MKOB" at any offset,
// accepted only when the record's lengths fit the file and its XXH3-64 matches) and walks the record
// headers to the first record at or past the range's end, counting. A byte pattern inside a record can
// fool the resync only with a matching 64-bit checksum; CheckMkSceneParts proves the parts anyway: the
// first part starts at the header, so each part's end, walked from a true record, is the next part's true
// begin, and the last must reach the end record with its object count.
struct MkSceneLayout {
  uint64_t file_size = 0;
  uint64_t body_begin = 0;  // the first record
  uint64_t body_end = 0;    // the end record
  uint64_t objects = 0;     // the end record's count
  uint32_t version = 0;
};
// Reads the header and the end record (verified). Errors name the file.
Result<MkSceneLayout> ReadMkSceneLayout(const std::string& path);
struct MkScenePart {
  bool found = false;    // a record starts in the range
  uint64_t begin = 0;    // that record's offset
  uint64_t end = 0;      // the first record at or past the range's end (body_end when none)
  uint64_t objects = 0;  // records from begin to end
};
// The part of [range_begin, range_end) (clamped to the body); range_begin == body_begin needs no resync.
Result<MkScenePart> FindMkScenePart(const std::string& path, const MkSceneLayout& layout,
                                    uint64_t range_begin, uint64_t range_end);
// Whether parts found for consecutive ranges covering the body chain into the whole file: Corruption
// naming the file and the offset where they do not.
Status CheckMkSceneParts(const std::string& path, const MkSceneLayout& layout,
                         const std::vector<uint64_t>& range_begins, const std::vector<MkScenePart>& parts);
// Streams a part's records (each verified as OpenMkSceneFile does); the first gets id first_id and is
// named in errors as object `first_index` of the file.
Result<std::unique_ptr<SceneSource>> OpenMkScenePart(const std::string& path, const MkSceneLayout& layout,
                                                     const MkScenePart& part, uint64_t first_index,
                                                     ObjectId first_id);

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
