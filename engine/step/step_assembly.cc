#include "engine/step/step_assembly.h"

#include <BRep_Builder.hxx>
#include <NCollection_DataMap.hxx>
#include <Quantity_Color.hxx>
#include <TCollection_AsciiString.hxx>
#include <TDF_LabelSequence.hxx>
#include <TDF_Tool.hxx>
#include <TDataStd_Name.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_ShapeMapHasher.hxx>
#include <TopoDS_Compound.hxx>
#include <XCAFDoc_ColorTool.hxx>
#include <XCAFDoc_DocumentTool.hxx>
#include <XCAFDoc_ShapeTool.hxx>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

namespace mktree {

namespace {

constexpr int kMaxAssemblyDepth = 256;

// The label's TDataStd_Name in UTF-8, or "".
std::string LabelName(const TDF_Label& label) {
  Handle(TDataStd_Name) name;
  if (!label.FindAttribute(TDataStd_Name::GetID(), name)) return "";
  return TCollection_AsciiString(name->Get()).ToCString();
}

std::string PathSegment(std::string name) {
  for (char& c : name)
    if (c == '/') c = '_';
  return name;
}

std::string Hex(const Quantity_Color& colour) {
  Standard_Real r, g, b;
  colour.Values(r, g, b, Quantity_TOC_sRGB);
  auto byte = [](double v) { return static_cast<unsigned>(std::lround(std::clamp(v, 0.0, 1.0) * 255)); };
  char text[8];
  std::snprintf(text, sizeof text, "#%02x%02x%02x", byte(r), byte(g), byte(b));
  return text;
}

// A part's pieces, in its own frame: what becomes one leaf per instance.
struct Piece {
  TopoDS_Shape shape;
  std::string suffix;  // "" for a part of one piece, else "/solid[k]", "/shell[k]", "/faces"
  std::vector<std::string> own_colours;   // the piece's colour, or its part's
  std::vector<std::string> face_colours;  // its faces' distinct colours
};

class LeafCollector {
 public:
  LeafCollector(const Handle(TDocStd_Document) & doc, std::string file)
      : shapes_(XCAFDoc_DocumentTool::ShapeTool(doc->Main())),
        colours_(XCAFDoc_DocumentTool::ColorTool(doc->Main())),
        file_(std::move(file)) {}

  Result<std::vector<StepLeaf>> Collect() {
    TDF_LabelSequence roots;
    shapes_->GetFreeShapes(roots);
    std::vector<TDF_Label> labels(roots.begin(), roots.end());
    const std::vector<std::string> segments = Segments(labels, labels);
    for (size_t i = 0; i < labels.size(); ++i)
      MKTREE_RETURN_IF_ERROR(Visit(labels[i], TopLoc_Location(), segments[i], std::nullopt, 0));
    return std::move(leaves_);
  }

 private:
  std::optional<std::string> ColourOf(const TDF_Label& label) const {
    Quantity_Color c;
    if (colours_->GetColor(label, XCAFDoc_ColorSurf, c) || colours_->GetColor(label, XCAFDoc_ColorGen, c))
      return Hex(c);
    return std::nullopt;
  }

  // The path segments of sibling instances (or roots): `named` gives the instance names, `referred` the
  // products'; equal segments get "[k]".
  static std::vector<std::string> Segments(const std::vector<TDF_Label>& named,
                                           const std::vector<TDF_Label>& referred) {
    std::vector<std::string> segments;
    std::map<std::string, int> count;
    for (size_t i = 0; i < named.size(); ++i) {
      std::string name = LabelName(named[i]);
      if (name.empty() || name.rfind("=>", 0) == 0) name = LabelName(referred[i]);  // "=>": OCCT's own
      if (name.empty()) name = "unnamed";
      segments.push_back(PathSegment(name));
      ++count[segments.back()];
    }
    std::map<std::string, int> seen;
    for (std::string& s : segments)
      if (count[s] > 1) s += "[" + std::to_string(++seen[s]) + "]";
    return segments;
  }

  Status Visit(const TDF_Label& label, const TopLoc_Location& at, const std::string& path,
               const std::optional<std::string>& instance_colour, int depth) {
    if (depth > kMaxAssemblyDepth)
      return Status::Corruption(file_ + ": " + path + ": assembly nested deeper than " +
                                std::to_string(kMaxAssemblyDepth) + " levels");
    if (!XCAFDoc_ShapeTool::IsAssembly(label)) {
      AddPart(label, at, path, instance_colour);
      return Status::Ok();
    }
    TDF_LabelSequence components;
    XCAFDoc_ShapeTool::GetComponents(label, components);
    std::vector<TDF_Label> named, referred;
    for (const TDF_Label& c : components) {
      TDF_Label part;
      if (!XCAFDoc_ShapeTool::GetReferredShape(c, part)) continue;
      named.push_back(c);
      referred.push_back(part);
    }
    const std::vector<std::string> segments = Segments(named, referred);
    for (size_t i = 0; i < named.size(); ++i) {
      std::optional<std::string> colour = ColourOf(named[i]);
      if (!colour) colour = instance_colour;
      MKTREE_RETURN_IF_ERROR(Visit(referred[i], at * XCAFDoc_ShapeTool::GetLocation(named[i]),
                                   path + "/" + segments[i], colour, depth + 1));
    }
    return Status::Ok();
  }

  void AddPart(const TDF_Label& part, const TopLoc_Location& at, const std::string& path,
               const std::optional<std::string>& instance_colour) {
    const std::vector<Piece>& pieces = PiecesOf(part);
    const std::string product = LabelName(part);
    for (const Piece& piece : pieces) {
      StepLeaf leaf;
      leaf.shape = piece.shape.Moved(at);
      leaf.path = path + piece.suffix;
      leaf.product = product;
      if (!piece.own_colours.empty())
        leaf.colours = piece.own_colours;
      else if (instance_colour)
        leaf.colours = {*instance_colour};
      else
        leaf.colours = piece.face_colours;
      leaves_.push_back(std::move(leaf));
    }
  }

  const std::vector<Piece>& PiecesOf(const TDF_Label& part) {
    TCollection_AsciiString entry;
    TDF_Tool::Entry(part, entry);
    auto [it, added] = pieces_.try_emplace(entry.ToCString());
    if (added) it->second = FindPieces(part);
    return it->second;
  }

  std::vector<Piece> FindPieces(const TDF_Label& part) const {
    const TopoDS_Shape shape = XCAFDoc_ShapeTool::GetShape(part);
    std::vector<Piece> pieces;
    if (shape.IsNull()) return pieces;
    int solids = 0, shells = 0;
    for (TopExp_Explorer e(shape, TopAbs_SOLID); e.More(); e.Next())
      pieces.push_back({e.Current(), "/solid[" + std::to_string(++solids) + "]", {}, {}});
    for (TopExp_Explorer e(shape, TopAbs_SHELL, TopAbs_SOLID); e.More(); e.Next())
      pieces.push_back({e.Current(), "/shell[" + std::to_string(++shells) + "]", {}, {}});
    TopoDS_Compound faces;
    BRep_Builder builder;
    builder.MakeCompound(faces);
    bool any_face = false;
    for (TopExp_Explorer e(shape, TopAbs_FACE, TopAbs_SHELL); e.More(); e.Next()) {
      builder.Add(faces, e.Current());
      any_face = true;
    }
    if (any_face) pieces.push_back({faces, "/faces", {}, {}});
    if (pieces.size() == 1) pieces[0].suffix.clear();
    // Colours on sub-shapes (the pieces' own, their faces'), by shape.
    NCollection_DataMap<TopoDS_Shape, std::string, TopTools_ShapeMapHasher> sub_colours;
    TDF_LabelSequence subs;
    XCAFDoc_ShapeTool::GetSubShapes(part, subs);
    for (const TDF_Label& sub : subs)
      if (const std::optional<std::string> c = ColourOf(sub))
        sub_colours.Bind(XCAFDoc_ShapeTool::GetShape(sub), *c);
    const std::optional<std::string> part_colour = ColourOf(part);
    for (Piece& p : pieces) {
      if (const std::string* own = sub_colours.Seek(p.shape))
        p.own_colours = {*own};
      else if (part_colour)
        p.own_colours = {*part_colour};
      if (sub_colours.IsEmpty()) continue;
      for (TopExp_Explorer f(p.shape, TopAbs_FACE); f.More(); f.Next()) {
        const std::string* c = sub_colours.Seek(f.Current());
        if (c && std::find(p.face_colours.begin(), p.face_colours.end(), *c) == p.face_colours.end())
          p.face_colours.push_back(*c);
      }
    }
    return pieces;
  }

  Handle(XCAFDoc_ShapeTool) shapes_;
  Handle(XCAFDoc_ColorTool) colours_;
  std::string file_;
  std::map<std::string, std::vector<Piece>> pieces_;  // by the part label's entry
  std::vector<StepLeaf> leaves_;
};

}  // namespace

Result<std::vector<StepLeaf>> CollectStepLeaves(const Handle(TDocStd_Document) & doc,
                                                const std::string& path_for_errors) {
  return LeafCollector(doc, path_for_errors).Collect();
}

}  // namespace mktree
