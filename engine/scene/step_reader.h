// Scene reader for STEP files (ISO 10303-21; AP203, AP214, AP242 and AP209 schemas) through OpenCASCADE's
// STEP translator with XCAF (names, colours and the assembly structure).
//
// What it produces
//   - One object per leaf solid of the assembly, with every instance's location applied: a part placed
//     three times gives three objects. A shell that is in no solid, and the faces of a part that are in no
//     shell (together, as one object), are objects too. Compounds are looked through.
//   - Names: the assembly path, the segments from the root to the part joined by '/'. A segment is the
//     instance's name where the file gives one (the NEXT_ASSEMBLY_USAGE_OCCURRENCE's name, which OCCT
//     keeps on the component), else the product's name, else "unnamed"; '/' inside a name becomes '_'.
//     Siblings whose segments are equal get "[k]" appended, k = 1, 2, ... in file order
//     ("engine/piston[2]/rod"). A part that holds several solids (or free shells) gives
//     "<path>/solid[k]" ("<path>/shell[k]", "<path>/faces") for each; one solid alone is just "<path>".
//   - Attributes (SceneObject::attributes): step_product (the part's product name), step_path (the name
//     as above, unchanged when the object is renamed later), step_colour ("#rrggbb", sRGB as in the
//     file: the solid's own colour, else its part's, else the innermost instance's that has one; when
//     none of them has one, one step_colour per distinct colour of its faces, in order of first use),
//     step_schema (the FILE_SCHEMA name, e.g. "AUTOMOTIVE_DESIGN"). SceneObject::source is the file.
//   - Units: the XCAF document's length unit is set to metres, and OCCT's transfer converts the file's
//     unit (millimetres, inches, ...) to it, so coordinates are in metres whatever the file's unit.
//   - Tessellation: each object's faces are meshed when the object is taken (BRepMesh_IncrementalMesh,
//     SceneReadOptions::chord_tolerance in metres and angular_deflection in radians), each face's
//     triangulation placed by the face's location and flipped for reversed faces, so that solids give
//     closed, outward-facing meshes where the file's B-rep is closed. The triangulation is kept on the
//     shared shape until the part's last instance is taken, so each part is meshed once.
//   - A leaf whose faces give no triangle (geometry the mesher cannot tessellate) is skipped: no object,
//     no id; the skipped leaves are counted and reported as one warning (SceneSource::TakeWarnings) naming
//     the first few by path and product. Leaves some of whose faces gave no triangle are kept and named in
//     another warning. Entities OCCT could not translate (a solid whose B-rep is broken: its shape is
//     missing) are counted in a third, naming the first by its entity ("#57 StepShape_ManifoldSolidBrep").
//
// Memory: the file's parsed entities (until the transfer ends) and the XCAF document (the B-rep of every
// part, once, not per instance; until the source is destroyed) are in RAM: that is the limit on the size
// of a STEP file. Triangles are made one object at a time.
//
// Errors, each naming the file: a file that does not start with the ISO-10303-21 header or that OCCT cannot
// parse (a truncated one, with OCCT's line) is Corruption; a schema other than the above is Unsupported; a
// file with no shape, or tessellation options that are not finite and positive, InvalidArgument. OCCT's
// own messages are not printed. OCCT dereferences what damaged files leave missing: while it reads or
// meshes, its signal handlers turn such faults into failed entities or leaves (engine/step/
// occt_signal_guard.h), reported as above, instead of a crash.
//
// OpenCASCADE is loaded on the first STEP file only: the reader lives in a module of its own
// (libmktree_step.so, built from engine/step/) that OpenStepFile loads with dlopen, so programs that read
// no STEP file do not map OCCT's 60-odd shared libraries (about 30 MiB of RSS). The module is looked for at
// $MKTREE_STEP_MODULE (alone, if set), else beside the library or program asking (<dir>/mktree/,
// <dir>/../lib/mktree/: an installed tree may move), then where the build put it, then where
// `cmake --install` of the build puts it; a module built from other headers is refused (its ABI tag
// differs). No module: Unsupported, naming the places tried.
//
// Thread-safety: a source is used by one thread at a time. Opening (reading the file) is serialised
// across threads: OCCT's translator keeps its parameters in process-wide state.
#pragma once

#include <memory>
#include <string>

#include "engine/scene/scene_source.h"

namespace mktree {

// Reads `path` as STEP with `options` (chord_tolerance, angular_deflection). The first object gets id
// `first_id`, the next first_id + 1, and so on.
Result<std::unique_ptr<SceneSource>> OpenStepFile(const std::string& path, ObjectId first_id,
                                                  const SceneReadOptions& options);

// The module's interface (engine/step/step_module.cc). Both sides are built from the same headers in the
// same build: the module exports kStepModuleAbiSymbol, a function returning the ABI tag the build gave it
// (MKTREE_STEP_MODULE_ABI, a hash of the headers whose types cross), and kStepModuleOpenSymbol.
struct StepModuleRequest {
  const std::string* path = nullptr;
  ObjectId first_id = 0;
  const SceneReadOptions* options = nullptr;
  std::unique_ptr<SceneSource>* source = nullptr;  // set on success
  Status* status = nullptr;                        // set on failure
};
using StepModuleAbiFunction = const char* (*)();
using StepModuleOpenFunction = void (*)(StepModuleRequest* request);
inline constexpr char kStepModuleAbiSymbol[] = "mktree_step_module_abi";
inline constexpr char kStepModuleOpenSymbol[] = "mktree_step_module_open";

}  // namespace mktree
