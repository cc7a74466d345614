// The leaves of a STEP file's assembly (engine/scene/step_reader.h, "What it produces"): every solid, free
// shell and set of free faces of every part, once per instance of the part, placed by the instances'
// locations, with its assembly path, product name and colours.
// Thread-safety: none (OCCT documents are used by one thread at a time).
#pragma once

#include <TDocStd_Document.hxx>
#include <TopoDS_Shape.hxx>
#include <string>
#include <vector>

#include "mktree/status.h"

namespace mktree {

struct StepLeaf {
  TopoDS_Shape shape;                // located in the file's world frame (metres)
  std::string path;                  // the object's name
  std::string product;               // the part's product name
  std::vector<std::string> colours;  // "#rrggbb": one for the leaf, or its faces' distinct colours
};

// The leaves in file order (depth first, components in file order, a part's solids before its free shells
// before its free faces). Corruption (naming `path_for_errors`) for an assembly nested deeper than 256.
Result<std::vector<StepLeaf>> CollectStepLeaves(const Handle(TDocStd_Document) & doc,
                                                const std::string& path_for_errors);

}  // namespace mktree
