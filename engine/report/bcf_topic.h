// A BCF topic as the writer (bcf_writer.h) makes it from a clash group and the reader (bcf_reader.h) reads
// it back: plain values, so that a round trip compares field by field. docs/clash_reports.md is the
// account of what a topic holds.
//
// Thread safety: plain values.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mktree/geometry.h"

namespace mktree {

// BCF-XML 2.1 (the default: what most BIM tools read) or 3.0.
enum class BcfVersion : uint8_t { k2_1, k3_0 };
// "2.1", "3.0".
const char* BcfVersionId(BcfVersion v);

// A perspective camera (world coordinates): where it is, where it looks, which way is up, the vertical
// field of view in degrees, and the picture's width / height.
struct BcfCamera {
  Vec3d position, direction, up;
  double field_of_view = 60;
  double aspect_ratio = 1;
};

// A colour ("RRGGBB", upper case) given to components, each an IFC GlobalId or, for an object with none, the
// id the authoring tool knows it by (BCF's AuthoringToolId: the object's name).
struct BcfColouring {
  std::string colour;
  std::vector<std::string> components;
};

struct BcfViewpoint {
  std::string guid;
  std::string file = "viewpoint.bcfv";  // in the topic folder
  std::string snapshot_file;            // "" when the viewpoint has no snapshot
  bool has_snapshot = false;            // reader: the snapshot file is in the archive
  BcfCamera camera;
  std::vector<std::string> selected;  // components, as in BcfColouring
  std::vector<BcfColouring> colours;
};

struct BcfTopic {
  std::string guid;  // lower-case UUID, also the topic folder's name
  std::string type, status, title, description;
  std::string creation_date, author;  // xs:dateTime, e.g. "2026-01-01T00:00:00Z"
  std::vector<std::string> labels;
  std::vector<std::string> files;  // the header's model file names
  std::vector<BcfViewpoint> viewpoints;
};

}  // namespace mktree
