// A stream of scene objects: readers (OBJ, assimp formats) and the tanker generator produce objects one
// at a time so that no caller needs the whole scene in RAM.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

class SceneSource {
 public:
  virtual ~SceneSource() = default;
  // Fills `*out` with the next object and returns true; returns false at the end of the stream.
  // Errors name the file and line. Object ids are assigned by the source: 0-based, in input order,
  // starting at `first_id` given at construction (so several files continue one numbering).
  virtual Result<bool> Next(SceneObject* out) = 0;
  // Remarks on input that was read but may not be what the file meant (e.g. coordinates a reader could
  // keep only at float32 precision), one line each, naming the file. Taken once the stream ends.
  virtual std::vector<std::string> TakeWarnings() { return {}; }
};

// Opens `path` for reading as a scene file: NotFound when missing, IOError "<path>: not a regular file" for
// a FIFO, directory or device (without blocking on a FIFO). Returns the descriptor (close-on-exec,
// blocking).
Result<int> OpenSceneInput(const std::string& path);

// Opens `path` by extension: .obj with the streaming OBJ reader, .mks with its reader, .ifc through web-ifc
// (ifc_reader.h; through assimp when MKTREE_IFC_READER=assimp), .mkifcs as a saved IFC stream; everything
// else through assimp.
// `spill_dir` takes a reader's scratch file (the OBJ vertices past its RAM budget); empty: $TMPDIR or /tmp.
Result<std::unique_ptr<SceneSource>> OpenSceneFile(const std::string& path, ObjectId first_id = 0,
                                                   const std::string& spill_dir = "");

}  // namespace mktree
