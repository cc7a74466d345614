// A picture of one clash group for its BCF topic and the HTML report: the group's objects in the colour
// of their worst class in the group (red hard, orange touch, yellow clearance) drawn through the faded
// scene around them, framed on the group's box, the worst pair outlined on top (engine/viz/clash_render.h
// with a focus box). An orthographic view along one axis (top by default), not the BCF camera's
// perspective: the snapshot shows where the objects meet, the viewpoint lets the tool fly there.
//
// Cost: RenderClashes draws the whole store leaf by leaf (clipped to the frame), so a snapshot reads the
// store's leaves once; a run renders only the groups asked for (BcfOptions::max_snapshots and the HTML
// report's). Memory: one byte per object of the store, the sample buffers and one leaf.
// Thread safety: RenderGroupSnapshot only reads `store`; the source it makes holds a reference to it.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/coordination/clash_issues.h"
#include "engine/report/bcf_writer.h"
#include "engine/store_format/store_file.h"
#include "engine/viz/raster.h"
#include "mktree/status.h"

namespace mktree {

struct GroupSnapshotOptions {
  RenderView view = RenderView::kTop;
  uint32_t width = 1200;  // pixels, 64..1500 (BCF's limit)
  uint32_t height = 900;
};

// The PNG bytes of `group`'s picture. Its records' object ids must be ids of `store` (InvalidArgument
// naming the store otherwise).
Result<std::vector<uint8_t>> RenderGroupSnapshot(const StoreReader& store, const ClashGroup& group,
                                                 const GroupSnapshotOptions& options);

// RenderGroupSnapshot as a snapshot source for WriteBcf and WriteHtmlReport. `store` must outlive it.
GroupSnapshotSource StoreSnapshotSource(const StoreReader& store, const GroupSnapshotOptions& options = {});

// `source` with its answers kept by group key, at most `max_groups` of them (later groups are rendered each
// time they are asked for): the BCF archive and the HTML report of one run then render each picture once.
// Errors are not kept. The returned source shares its cache between its copies; one thread at a time.
GroupSnapshotSource MemoizedSnapshotSource(GroupSnapshotSource source, uint64_t max_groups);

}  // namespace mktree
