// What an assimp node says about its object besides geometry, as ObjectAttributes: its metadata
// (glTF extras, FBX properties, IFC property sets, ...) and, for IFC, the entity's type, name and GlobalId,
// which assimp's IFC importer folds into the node name "<IfcType>_<Name>_<GlobalId>".
#pragma once

#include <string_view>
#include <vector>

#include "mktree/scene.h"

struct aiMetadata;

namespace mktree {

// Appends `metadata`'s entries: numbers in shortest round-trip form, booleans as "true"/"false", vectors
// as "x y z", nested metadata flattened to "outer.inner" keys (at most 16 levels; deeper entries dropped).
void AppendMetadataAttributes(const aiMetadata& metadata, std::vector<ObjectAttribute>* out);

// For a node name of the IFC importer's form, appends "ifc_type", "ifc_name" and "ifc_global_id"; returns
// false (appending nothing) when the name is not of that form.
bool AppendIfcNameAttributes(std::string_view node_name, std::vector<ObjectAttribute>* out);

}  // namespace mktree
