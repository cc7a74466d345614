#include "engine/clash/clash_reads.h"

#include <algorithm>

namespace mktree::clash {

void IoCount::Mark(const LeafInfo& info, uint64_t base) {
  for (uint64_t p = base + info.first_page; p < base + info.first_page + info.page_count; ++p) {
    if (p >= touched.size()) touched.resize(p + 1, 0);
    touched[p] = 1;
  }
}

void IoCount::Fill(ClashStats* s) const {
  s->pages_read = q.pages_read;
  s->pages_touched = q.pages_touched;
  s->distinct_pages = static_cast<uint64_t>(std::count(touched.begin(), touched.end(), 1));
}

Status ReadPinned(const LeafSource& st, uint32_t leaf, IoCount* io, std::vector<uint64_t>* seen,
                  PinnedLeaf* out, uint64_t page_base) {
  const LeafInfo& info = st.reader().tree().leaves[leaf];
  out->seen.swap(*seen);
  const Status s = st.Read(leaf, &io->q, out);
  out->seen.swap(*seen);
  if (s.ok()) io->Mark(info, page_base);
  return s;
}

Status DecodeMesh(const LeafSource& st, const ObjectEntryView& e, Mesh* mesh) {
  return st.DecodeMesh(e, mesh);
}

std::optional<EdgeCheck> StoredEdges(const ObjectEntryView& e) {
  if (!(e.shape_flags & kShapeKnown)) return std::nullopt;
  EdgeCheck edges;
  edges.even = (e.shape_flags & kShapeEvenEdges) != 0;
  edges.closed = (e.shape_flags & kShapeClosed) != 0;
  return edges;
}

uint64_t StorePages(const MKTree& tree) {
  uint64_t n = 0;
  for (const LeafInfo& l : tree.leaves) n += l.page_count;
  return n;
}

}  // namespace mktree::clash
