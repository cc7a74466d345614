// Scene reader for IFC (2x3, 4, 4.3) through web-ifc: runs tools/ifc/mktree-ifc.mjs under Node.js as a
// subprocess and streams the objects it writes to a pipe, so the engine stays C++ and keeps one object in
// memory (web-ifc holds the model in the Node process).
//
// What it produces (tools/ifc/mktree-ifc.mjs says how): one object per IFC product with a body
// representation (openings subtracted, mapped items merged under their product), named by the product's
// Name (else "<IfcType> <GlobalId>"), source = the IFC file as given, attributes ifc_global_id, ifc_type,
// ifc_name, ifc_schema, ifc_storey, ifc_container, ifc_aggregate, ifc_fills, ifc_voids, ifc_material
// (repeatable), ifc_spatial ("true" on spaces, openings and other spatial elements) and
// "pset:<Set>.<Property>" (property sets and element quantities, the type's sets after the occurrence's).
// Coordinates: the IFC model's frame, Z up, metres, IfcMapConversion applied where the file has one.
//
// The program: $MKTREE_IFC_READER (the .mjs, or the folder holding it) or the source tree's tools/ifc
// (compiled in); MKTREE_IFC_READER=assimp makes OpenSceneFile read .ifc through assimp instead. Node.js:
// $MKTREE_NODE or `node` on PATH. web-ifc must be installed next to the program (scripts/setup.sh runs
// `npm ci --prefix tools/ifc`).
//
// Stream (the program's stdout; little-endian, strings are a u32 byte count and UTF-8 bytes):
//   header "MKIFCS\0\0" u32 version (1) u32 flags (0); then records, each a 4-byte tag:
//   "MKOB" str name, u32 n, n * (str key, str value), u32 vertices, u32 triangles, f64[3v], u32[3t]
//   "MKWN" str text (a product without geometry, ...: a warning, the rest is read)
//   "MKER" str text (the file cannot be read), "MKEN" u32 0, u64 objects: the end, then end of file.
//
// Errors, each naming the IFC file: NotFound (no file), Unsupported (schema web-ifc does not read),
// Corruption (truncated or not IFC; a malformed object: non-finite coordinate, index out of range, named
// by its GlobalId), IOError (Node.js or web-ifc missing: says what to install; the program died). The
// subprocess is killed and reaped when the source is destroyed early.
//
// Thread-safety: a source is used by one thread at a time; distinct sources are independent.
#pragma once

#include <memory>
#include <string>

#include "engine/scene/scene_source.h"

namespace mktree {

// Whether MKTREE_IFC_READER asks for the assimp IFC reader ("assimp"), kept for comparison.
bool IfcThroughAssimp();

// The IFC reader program's path: $MKTREE_IFC_READER (a file, or a folder holding mktree-ifc.mjs) or the
// source tree's tools/ifc/mktree-ifc.mjs.
std::string IfcReaderProgram();

// Streams the products of `path`; the first object gets id `first_id`. `scratch_dir` takes the unlinked
// file that keeps the subprocess's stderr (empty: $TMPDIR or /tmp).
Result<std::unique_ptr<SceneSource>> OpenIfcFile(const std::string& path, ObjectId first_id = 0,
                                                 const std::string& scratch_dir = "");

// Reads a saved stream (`node tools/ifc/mktree-ifc.mjs model.ifc > model.mkifcs`), as OpenIfcFile reads
// the program's output: IFC converted once, built many times without Node. Objects' source is `path`.
// Errors name the file: Corruption when it is not an MKIFCS stream or is truncated.
Result<std::unique_ptr<SceneSource>> OpenIfcStreamFile(const std::string& path, ObjectId first_id = 0);

}  // namespace mktree
