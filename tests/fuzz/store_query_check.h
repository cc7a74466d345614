// Shared by the store fuzz targets: open a store file through the public API and query it, checking what
// every answer must be whatever the store holds: sorted ids, no duplicate, only objects the store has.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <span>
#include <vector>

#include "fuzz_util.h"
#include "mktree/database.h"

namespace mktree::fuzz {

// MKTREE_FUZZ_NO_ANSWER_CHECK=1 turns the answer check off, to look for crashes and hangs past a known
// wrong-answer bug that would otherwise stop nearly every run.
inline bool AnswerCheckOff() {
  static const bool off = std::getenv("MKTREE_FUZZ_NO_ANSWER_CHECK") != nullptr;
  return off;
}

inline void CheckAnswer(const Database& db, const std::vector<ObjectId>& hits) {
  if (AnswerCheckOff()) return;
  for (size_t i = 0; i < hits.size(); ++i) {
    if (hits[i] >= db.object_count()) std::abort();     // an object the store does not have
    if (i > 0 && hits[i] <= hits[i - 1]) std::abort();  // unsorted or duplicated
  }
}

inline void RunQueries(const Database& db, const std::vector<Box3d>& extra) {
  std::vector<Box3d> boxes;
  const Box3d b = db.bounds();
  if (!b.empty()) {
    Box3d whole = b, centre;
    for (int i = 0; i < 3; ++i) {
      const double c = (b.min[i] + b.max[i]) / 2;
      centre.min[i] = centre.max[i] = std::isfinite(c) ? c : 0.0;
    }
    boxes.push_back(whole);
    boxes.push_back(centre);
  }
  boxes.insert(boxes.end(), extra.begin(), extra.end());
  QueryResult r;
  std::vector<ObjectId> streamed;
  for (const Box3d& q : boxes) {
    for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
      if (db.Run(Query::Point(Vec3d{q.min[0], q.min[1], q.min[2]}, mode), &r).ok()) CheckAnswer(db, r.hits);
      const Query box = Query::Box(q, mode);
      if (!db.Run(box, &r).ok()) continue;
      CheckAnswer(db, r.hits);
      if (AnswerCheckOff()) continue;
      // The streaming and counting paths, which sort nothing: the same ids, or an error.
      streamed.clear();
      const Status st = db.VisitSpans(
          box,
          [&](std::span<const ObjectId> ids) { streamed.insert(streamed.end(), ids.begin(), ids.end()); },
          nullptr);
      std::sort(streamed.begin(), streamed.end());
      if (st.ok() && streamed != r.hits) std::abort();
      BatchOptions count;
      count.threads = 1;
      count.ids = false;
      const uint64_t want = r.hits.size();
      (void)db.RunBatchStreamed({box}, count, [want](uint64_t, const QueryResult& c) {
        if (c.stats.hits != want) std::abort();
        return Status::Ok();
      });
    }
  }
}

// `named`: write the store to a named file (HDF5 needs one) instead of a memfd.
inline void OpenAndQuery(const std::vector<uint8_t>& file, const std::vector<Box3d>& queries,
                         bool named = false) {
  const std::string& path = (named ? InputFile::Named() : InputFile::Get()).Write(file.data(), file.size());
  // MKTREE_FUZZ_SAVE_STORE=FILE keeps the store (for triage with `mktree info` and `mktree query`).
  if (const char* save = std::getenv("MKTREE_FUZZ_SAVE_STORE")) {
    std::ofstream(save, std::ios::binary)
        .write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));
  }
  OpenOptions options;
  options.cache_pages = 2;  // small, so that queries evict
  auto db = Database::Open(path, options);
  if (!db.ok()) {
    Refused(db.status().ToString());
    return;
  }
  ++g_accepted;
  for (uint64_t i = 0; i < (*db)->object_count() && i < 64; ++i) (void)(*db)->ObjectName(i);
  for (uint64_t i = 0; i < (*db)->object_count() && i < 8; ++i) {
    (void)(*db)->Object(static_cast<ObjectId>(i));
    (void)(*db)->ObjectGeometry(static_cast<ObjectId>(i));
  }
  RunQueries(**db, queries);
}

}  // namespace mktree::fuzz
