// One STEP leaf's faces as a triangle mesh (engine/scene/step_reader.h, "Tessellation").
// Thread-safety: none (the leaf's shape is shared with its part's other instances).
#pragma once

#include <TopoDS_Shape.hxx>
#include <string>

#include "mktree/scene.h"

namespace mktree {

struct StepTessellation {
  Mesh mesh;                   // vertices welded where positions are equal
  int faces = 0;               // faces of the shape
  int faces_without_mesh = 0;  // faces the mesher gave no triangle
  std::string failure;         // OCCT's exception, if meshing threw (then the mesh is empty)
};

// Meshes `shape` (BRepMesh_IncrementalMesh, absolute chord tolerance and angular deflection in the
// shape's unit and radians) and gathers its faces' triangles placed and oriented.
StepTessellation TessellateStepShape(const TopoDS_Shape& shape, double chord_tolerance,
                                     double angular_deflection);

}  // namespace mktree
