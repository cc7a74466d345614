// write_step_assembly OUT.step [--extra-parts N]: writes the STEP test assembly of step_assembly_layout.h
// (AP214, millimetres) with OpenCASCADE's XCAF writer: names, colours, nested instances with locations.
// Run by hand to regenerate tests/data/step/engine_assembly.step, and by bench/README.md's STEP section
// for larger files.
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <Interface_Static.hxx>
#include <Quantity_Color.hxx>
#include <STEPCAFControl_Writer.hxx>
#include <TDataStd_Name.hxx>
#include <TDocStd_Document.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Compound.hxx>
#include <TopoDS_Shell.hxx>
#include <XCAFApp_Application.hxx>
#include <XCAFDoc_ColorTool.hxx>
#include <XCAFDoc_DocumentTool.hxx>
#include <XCAFDoc_ShapeTool.hxx>
#include <cstdio>
#include <cstdlib>
#include <gp_Pln.hxx>
#include <gp_Trsf.hxx>
#include <string>

#include "step_assembly_layout.h"

namespace {

using mktree::step_test::BoxMm;
namespace layout = mktree::step_test;

TopoDS_Shape Box(const BoxMm& b) {
  return BRepPrimAPI_MakeBox(gp_Pnt(b.x0, b.y0, b.z0), gp_Pnt(b.x1, b.y1, b.z1)).Shape();
}

Quantity_Color Colour(unsigned rgb) {
  return Quantity_Color(((rgb >> 16) & 255) / 255.0, ((rgb >> 8) & 255) / 255.0, (rgb & 255) / 255.0,
                        Quantity_TOC_sRGB);
}

TopLoc_Location Move(const std::array<double, 3>& at, bool quarter_turn = false) {
  gp_Trsf t;
  if (quarter_turn) t.SetRotation(gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), M_PI / 2);
  gp_Trsf move;
  move.SetTranslation(gp_Vec(at[0], at[1], at[2]));
  return TopLoc_Location(move * t);
}

struct Writer {
  Handle(XCAFDoc_ShapeTool) shapes;
  Handle(XCAFDoc_ColorTool) colours;

  TDF_Label Part(const TopoDS_Shape& shape, const char* name) {
    const TDF_Label label = shapes->AddShape(shape, false);
    TDataStd_Name::Set(label, name);
    return label;
  }
  TDF_Label Assembly(const char* name) {
    const TDF_Label label = shapes->NewShape();
    TDataStd_Name::Set(label, name);
    return label;
  }
  TDF_Label Place(const TDF_Label& assembly, const TDF_Label& part, const TopLoc_Location& at,
                  const char* instance_name) {
    const TDF_Label component = shapes->AddComponent(assembly, part, at);
    if (instance_name) TDataStd_Name::Set(component, instance_name);
    return component;
  }
};

TopoDS_Shape OpenCover() {
  const TopoDS_Shape box = Box(layout::kCover);
  TopoDS_Shell shell;
  BRep_Builder builder;
  builder.MakeShell(shell);
  for (TopExp_Explorer f(box, TopAbs_FACE); f.More(); f.Next()) {
    // The top face (every vertex at z = kCover.z1) is left out.
    bool top = true;
    for (TopExp_Explorer v(f.Current(), TopAbs_VERTEX); v.More(); v.Next())
      top = top && BRep_Tool::Pnt(TopoDS::Vertex(v.Current())).Z() == layout::kCover.z1;
    if (!top) builder.Add(shell, f.Current());
  }
  return shell;
}

void AddExtraParts(Writer& w, const TDF_Label& root, int extra_parts) {
  for (int k = 0; k < extra_parts; ++k) {
    const BoxMm b = layout::ExtraPart(k);
    TopoDS_Shape shape;
    if (k % 2 == 0) {
      shape = Box(b);
    } else {
      const gp_Ax2 axis(gp_Pnt((b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2, b.z0), gp_Dir(0, 0, 1));
      shape = BRepPrimAPI_MakeCylinder(axis, (b.x1 - b.x0) / 2, b.z1 - b.z0).Shape();
    }
    const std::string name = "extra_" + std::to_string(k);
    w.Place(root, w.Part(shape, name.c_str()), TopLoc_Location(), nullptr);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2 && !(argc == 4 && std::string(argv[2]) == "--extra-parts")) {
    std::fprintf(stderr, "usage: write_step_assembly OUT.step [--extra-parts N]\n");
    return 2;
  }
  const int extra_parts = argc == 4 ? std::atoi(argv[3]) : 0;
  Handle(TDocStd_Document) doc;
  XCAFApp_Application::GetApplication()->NewDocument("MDTV-XCAF", doc);
  Writer w{XCAFDoc_DocumentTool::ShapeTool(doc->Main()), XCAFDoc_DocumentTool::ColorTool(doc->Main())};

  const TDF_Label engine = w.Assembly("engine");
  const TDF_Label block = w.Part(Box(layout::kBlock), "block");
  w.colours->SetColor(block, Colour(layout::kBlockColour), XCAFDoc_ColorSurf);
  w.Place(engine, block, Move(layout::kBlockAt), "block");

  const TDF_Label piston = w.Assembly("piston");
  const TopoDS_Shape head_shape = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)),
                                                           layout::kHeadRadius, layout::kHeadHeight)
                                      .Shape();
  const TDF_Label head = w.Part(head_shape, "head");
  for (TopExp_Explorer f(head_shape, TopAbs_FACE); f.More(); f.Next())
    w.colours->SetColor(w.shapes->AddSubShape(head, f.Current()), Colour(layout::kHeadColour),
                        XCAFDoc_ColorSurf);
  w.Place(piston, head, TopLoc_Location(), "head");
  w.Place(piston, w.Part(Box(layout::kRod), "rod"), Move(layout::kRodAt), "rod");
  for (int i = 0; i < layout::kPistons; ++i)
    w.Place(engine, piston, Move(layout::PistonAt(i), layout::PistonTurned(i)), nullptr);

  TopoDS_Compound two;
  BRep_Builder builder;
  builder.MakeCompound(two);
  builder.Add(two, Box(layout::kBracketA));
  builder.Add(two, Box(layout::kBracketB));
  const TDF_Label bracket = w.Part(two, "bracket");
  w.colours->SetColor(bracket, Colour(layout::kBracketColour), XCAFDoc_ColorSurf);
  w.Place(engine, bracket, Move(layout::kBracketAt), "bracket");

  w.Place(engine, w.Part(OpenCover(), "cover"), Move(layout::kCoverAt), "cover");
  const BoxMm& s = layout::kSheet;
  const TopoDS_Shape sheet =
      BRepBuilderAPI_MakeFace(gp_Pln(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), s.x0, s.x1, s.y0, s.y1).Shape();
  w.Place(engine, w.Part(sheet, "sheet"), Move(layout::kSheetAt), "sheet");
  AddExtraParts(w, engine, extra_parts);
  w.shapes->UpdateAssemblies();

  Interface_Static::SetCVal("write.step.schema", "AP214IS");
  Interface_Static::SetCVal("write.step.unit", "MM");
  STEPCAFControl_Writer writer;
  writer.SetColorMode(true);
  writer.SetNameMode(true);
  if (!writer.Transfer(doc, STEPControl_AsIs) || writer.Write(argv[1]) != IFSelect_RetDone) {
    std::fprintf(stderr, "%s: not written\n", argv[1]);
    return 1;
  }
  return 0;
}
