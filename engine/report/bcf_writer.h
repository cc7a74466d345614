// `mktree clash --bcf OUT.bcf`: a clash run's groups as a BCF-XML archive (buildingSMART's BIM
// Collaboration Format, version 2.1 or 3.0) that BIM tools open: one topic per group, with a viewpoint
// (a perspective camera framing the group, its objects selected and coloured by class) and, when a
// snapshot source is given, a PNG snapshot of the group. docs/clash_reports.md is the account.
//
//   bcf.version, project.bcfp (3.0: and extensions.xml)
//   <topic guid>/markup.bcf, <topic guid>/viewpoint.bcfv, <topic guid>/snapshot.png
//
// The topic GUID is a name-based UUID (version 5) of the group's key, the viewpoint's of the key and
// "/viewpoint": the same group exported again keeps its GUIDs, so a BIM tool updates the topic it holds.
// With a fixed creation time (BcfOptions::creation_time) the same run gives a byte-identical archive.
//
// The archive is written under a temporary name beside `path` and renamed over it at the end: on any
// error nothing is left at `path` (an earlier file there is untouched) and no temporary stays.
// Memory: the run, plus one entry (one topic's XML or one snapshot) at a time.
// Thread safety: WriteBcf reads `run` only; the snapshot source is called on the calling thread.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "engine/coordination/clash_issues.h"
#include "engine/report/bcf_topic.h"
#include "mktree/status.h"

namespace mktree {

// A group's snapshot as PNG bytes (at most 1500 pixels on a side, as BCF asks): group_snapshot.h makes one
// from a store.
using GroupSnapshotSource = std::function<Result<std::vector<uint8_t>>(const ClashGroup&)>;

struct BcfOptions {
  BcfVersion version = BcfVersion::k2_1;
  std::string author = "mktree";  // CreationAuthor
  // CreationDate of every topic and the archive entries' times, in seconds since 1970-01-01 UTC; < 0: the
  // environment's SOURCE_DATE_EPOCH if set, else now.
  int64_t creation_time = -1;
  std::string project_name;              // "": the store's file name (ClashRun::store)
  std::string open_status = "Open";      // TopicStatus of a group that is new, active or not compared
  std::string closed_status = "Closed";  // TopicStatus of a resolved group
  GroupSnapshotSource snapshot;          // empty: no snapshots
  uint64_t max_snapshots = UINT64_MAX;   // snapshots for the first groups only (the worst, in run order)
  uint32_t listed_members = 20;          // clashes listed in a topic's description; the rest are counted
  uint32_t max_components = 1000;        // objects selected and coloured per viewpoint
  double field_of_view = 60;             // degrees (BCF 2.1 allows 45 to 60)
  double aspect_ratio = 4.0 / 3.0;       // the camera's width / height (the snapshot's, default 1200 x 900)
};

struct BcfWriteReport {
  uint64_t topics = 0;
  uint64_t snapshots = 0;
  uint64_t components = 0;  // selected objects over all viewpoints
  uint64_t bytes = 0;       // the archive's size
};

// Writes `run` as a BCF archive at `path`. Errors name the path: InvalidArgument for a group without a key
// or two groups with one key (their topics would share a GUID), IOError for what cannot be written, and a
// snapshot source's own error.
Result<BcfWriteReport> WriteBcf(const ClashRun& run, const std::string& path, const BcfOptions& options);

// The topic WriteBcf makes of `group` (snapshot_file set when it has a snapshot): for tests and re-export.
BcfTopic BcfTopicOf(const ClashGroup& group, const BcfOptions& options, bool with_snapshot);
// UUID v5 of the group's key (the topic) and of the key and "/viewpoint".
std::string BcfTopicGuid(const std::string& group_key);
std::string BcfViewpointGuid(const std::string& group_key);
// The camera that frames `box`: from above, along the diagonal (1, -1, 1) (the south-east corner seen
// from above), far enough that the box's bounding sphere fills the field of view.
BcfCamera BcfCameraFraming(const Box3d& box, double field_of_view, double aspect_ratio);
// "YYYY-MM-DDThh:mm:ssZ".
std::string BcfDateTime(int64_t seconds_since_epoch);

}  // namespace mktree
