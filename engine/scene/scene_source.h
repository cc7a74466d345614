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

// How scene files are read: what a build's options say to the readers.
struct SceneReadOptions {
  // Where a reader's scratch file goes (the OBJ vertices past its RAM budget); empty: $TMPDIR or /tmp.
  std::string spill_dir;
  // STEP tessellation (engine/scene/step_reader.h): the largest distance in metres between a face and its
  // triangles (BRepMesh's linear deflection), and the largest angle in radians between the normals of
  // adjacent triangles (its angular deflection). Both must be finite and positive.
  double chord_tolerance = 0.0005;
  double angular_deflection = 0.5;
};

// Opens `path` by extension: .obj with the streaming OBJ reader, .mks with its reader, .ifc through web-ifc
// (ifc_reader.h; through assimp when MKTREE_IFC_READER=assimp), .mkifcs as a saved IFC stream, .step/.stp
// (any case) with the STEP reader (OpenCASCADE, engine/scene/step_reader.h); everything else through assimp.
Result<std::unique_ptr<SceneSource>> OpenSceneFile(const std::string& path, ObjectId first_id,
                                                   const SceneReadOptions& options);
// The same with the default options but `spill_dir`.
Result<std::unique_ptr<SceneSource>> OpenSceneFile(const std::string& path, ObjectId first_id = 0,
                                                   const std::string& spill_dir = "");

}  // namespace mktree
