#include "engine/step/step_tessellation.h"

#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <Poly_Triangulation.hxx>
#include <Standard_ErrorHandler.hxx>
#include <Standard_Failure.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <array>
#include <cstring>
#include <unordered_map>

#include "engine/step/occt_signal_guard.h"

namespace mktree {

namespace {

struct PositionHash {
  size_t operator()(const std::array<double, 3>& p) const {
    uint64_t h = 1469598103934665603ull;
    for (double v : p) {
      uint64_t bits;
      v = v == 0 ? 0.0 : v;  // -0 and 0 weld
      std::memcpy(&bits, &v, 8);
      h = (h ^ bits) * 1099511628211ull;
    }
    return h;
  }
};

// Appends the face's triangles; false when it has none.
bool AppendFace(const TopoDS_Face& face, Mesh* mesh,
                std::unordered_map<std::array<double, 3>, uint32_t, PositionHash>* index) {
  TopLoc_Location at;
  const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, at);
  if (tri.IsNull() || tri->NbTriangles() == 0) return false;
  const gp_Trsf placed = at.Transformation();
  std::vector<uint32_t> node_index(static_cast<size_t>(tri->NbNodes()) + 1);
  for (int i = 1; i <= tri->NbNodes(); ++i) {
    const gp_Pnt p = tri->Node(i).Transformed(placed);
    const std::array<double, 3> key{p.X() == 0 ? 0.0 : p.X(), p.Y() == 0 ? 0.0 : p.Y(),
                                    p.Z() == 0 ? 0.0 : p.Z()};
    auto [it, added] = index->try_emplace(key, static_cast<uint32_t>(mesh->vertex_count()));
    if (added) mesh->vertices.insert(mesh->vertices.end(), key.begin(), key.end());
    node_index[static_cast<size_t>(i)] = it->second;
  }
  const bool reversed = face.Orientation() == TopAbs_REVERSED;
  for (int t = 1; t <= tri->NbTriangles(); ++t) {
    int a, b, c;
    tri->Triangle(t).Get(a, b, c);
    if (reversed) std::swap(b, c);
    const uint32_t ia = node_index[static_cast<size_t>(a)], ib = node_index[static_cast<size_t>(b)],
                   ic = node_index[static_cast<size_t>(c)];
    if (ia == ib || ib == ic || ia == ic) continue;  // collapsed by the weld
    mesh->triangles.insert(mesh->triangles.end(), {ia, ib, ic});
  }
  return true;
}

}  // namespace

StepTessellation TessellateStepShape(const TopoDS_Shape& shape, double chord_tolerance,
                                     double angular_deflection) {
  StepTessellation out;
  const OcctSignalGuard signals;
  try {
    OCC_CATCH_SIGNALS
    BRepMesh_IncrementalMesh mesher(shape, chord_tolerance, /*isRelative=*/false, angular_deflection,
                                    /*isInParallel=*/false);
    std::unordered_map<std::array<double, 3>, uint32_t, PositionHash> index;
    for (TopExp_Explorer f(shape, TopAbs_FACE); f.More(); f.Next()) {
      ++out.faces;
      if (!AppendFace(TopoDS::Face(f.Current()), &out.mesh, &index)) ++out.faces_without_mesh;
    }
  } catch (const Standard_Failure& e) {
    out.mesh = Mesh();
    out.failure = e.GetMessageString();
    if (out.failure.empty()) out.failure = e.DynamicType()->Name();
  }
  return out;
}

}  // namespace mktree
