// Reads a BCF-XML archive (2.1 or 3.0; what bcf_writer.h writes, and other tools' archives in the parts it
// knows) back into topics: guid, type, status, title, description, labels, header files, and per viewpoint
// the perspective camera, the selected components, the colours and whether the snapshot file is in the
// archive. For the round-trip tests, and for a later export that updates the topics a tool holds.
//
// Errors name the archive and the entry (and the line for bad XML): not a zip archive, no bcf.version, a
// version other than 2.0, 2.1 or 3.0, a markup.bcf without a Topic, a viewpoint file named but missing.
// Memory: one entry at a time plus the topics read.
// Thread safety: a pure function of the file.
#pragma once

#include <string>
#include <vector>

#include "engine/report/bcf_topic.h"
#include "mktree/status.h"

namespace mktree {

struct BcfArchiveContents {
  std::string version;           // VersionId of bcf.version: "2.1", "3.0"
  std::string project_name;      // from project.bcfp, "" when absent
  std::vector<BcfTopic> topics;  // in the archive's order
};

Result<BcfArchiveContents> ReadBcf(const std::string& path);

}  // namespace mktree
