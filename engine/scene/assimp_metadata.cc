#include "engine/scene/assimp_metadata.h"

#include <assimp/scene.h>  // metadata.h needs the types scene.h includes first

#include <charconv>
#include <cstdint>
#include <string>

namespace mktree {
namespace {

constexpr int kMaxMetadataDepth = 16;
constexpr size_t kIfcGlobalIdLength = 22;  // IFC's compressed GUID: 22 characters of 0-9A-Za-z_$

template <typename T>
std::string Number(T v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

bool IsGlobalIdChar(char c) {
  return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_' || c == '$';
}

void Append(const aiMetadata& m, const std::string& prefix, int depth, std::vector<ObjectAttribute>* out) {
  for (unsigned i = 0; i < m.mNumProperties; ++i) {
    const aiMetadataEntry& e = m.mValues[i];
    if (e.mData == nullptr) continue;
    std::string key = prefix + std::string(m.mKeys[i].C_Str(), m.mKeys[i].length);
    std::string value;
    switch (e.mType) {
      case AI_BOOL:
        value = *static_cast<const bool*>(e.mData) ? "true" : "false";
        break;
      case AI_INT32:
        value = Number(*static_cast<const int32_t*>(e.mData));
        break;
      case AI_UINT64:
        value = Number(*static_cast<const uint64_t*>(e.mData));
        break;
      case AI_FLOAT:
        value = Number(*static_cast<const float*>(e.mData));
        break;
      case AI_DOUBLE:
        value = Number(*static_cast<const double*>(e.mData));
        break;
      case AI_AISTRING: {
        const aiString& s = *static_cast<const aiString*>(e.mData);
        value.assign(s.C_Str(), s.length);
        break;
      }
      case AI_AIVECTOR3D: {
        const aiVector3D& v = *static_cast<const aiVector3D*>(e.mData);
        value = Number(v.x) + " " + Number(v.y) + " " + Number(v.z);
        break;
      }
      case AI_AIMETADATA:
        if (depth + 1 < kMaxMetadataDepth)
          Append(*static_cast<const aiMetadata*>(e.mData), key + ".", depth + 1, out);
        continue;
      default: {
        // Types added after this reader (AI_INT64, AI_UINT32 in newer assimp) by their numeric tag, so
        // the code builds against every assimp Debian ships.
        if (static_cast<int>(e.mType) == 8)
          value = Number(*static_cast<const int64_t*>(e.mData));
        else if (static_cast<int>(e.mType) == 9)
          value = Number(*static_cast<const uint32_t*>(e.mData));
        else
          continue;
      }
    }
    out->push_back({std::move(key), std::move(value)});
  }
}

}  // namespace

void AppendMetadataAttributes(const aiMetadata& metadata, std::vector<ObjectAttribute>* out) {
  Append(metadata, "", 0, out);
}

bool AppendIfcNameAttributes(std::string_view node_name, std::vector<ObjectAttribute>* out) {
  const size_t type_end = node_name.find('_');
  if (type_end == std::string_view::npos || !node_name.starts_with("Ifc") ||
      node_name.size() < type_end + 2 + kIfcGlobalIdLength)
    return false;
  const size_t id_begin = node_name.size() - kIfcGlobalIdLength;
  if (node_name[id_begin - 1] != '_') return false;
  const std::string_view id = node_name.substr(id_begin);
  for (const char c : id)
    if (!IsGlobalIdChar(c)) return false;
  out->push_back({"ifc_type", std::string(node_name.substr(0, type_end))});
  out->push_back({"ifc_name", std::string(node_name.substr(type_end + 1, id_begin - 1 - (type_end + 1)))});
  out->push_back({"ifc_global_id", std::string(id)});
  return true;
}

}  // namespace mktree
