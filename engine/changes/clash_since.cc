// ClashSince (mktree/changes.h): the pairs a change adds and removes, from a clash of the changed objects
// only, at both revisions. A pair with no changed object is the same at both (neither object's geometry
// changed), so the difference of the two focused clashes is the difference of the two full ones.
#include <algorithm>
#include <chrono>
#include <set>

#include "engine/clash/clash_engine.h"
#include "engine/core/guarded.h"
#include "engine/query/revision_database.h"
#include "mktree/changes.h"
#include "mktree/database.h"

namespace mktree {

Status ClashSince(const Database& now, const Database& then, const ClashOptions& options,
                  const ClashChangeVisitor& visit, ClashStats* stats) {
  return Guarded(now.path(), [&]() -> Status {
    const auto start = std::chrono::steady_clock::now();
    ClashStats local;
    ClashStats& total = stats ? *stats : local;
    total = ClashStats();
    if (then.path() != now.path())
      return Status::InvalidArgument("clash since: " + then.path() + " and " + now.path() +
                                     " are not revisions of one store");
    if (then.revision() > now.revision())
      return Status::InvalidArgument(now.path() + ": clash since revision " +
                                     std::to_string(then.revision()) + ", which is newer than revision " +
                                     std::to_string(now.revision()));
    if (then.revision() == now.revision()) return Status::Ok();
    const RevisionManifest* m_now = RevisionManifestOf(now);
    const RevisionManifest* m_then = RevisionManifestOf(then);
    if (!m_now || !m_then || m_now->history != m_then->history)
      return Status::InvalidArgument(now.path() + ": revisions " + std::to_string(then.revision()) + " and " +
                                     std::to_string(now.revision()) + " are not of one history of changes");
    MKTREE_ASSIGN_OR_RETURN(const std::vector<ObjectId> touched, TouchedSince(now, then.revision()));
    ClashOptions o = options;
    o.max_pairs = std::numeric_limits<uint64_t>::max();
    o.progress = nullptr;
    std::vector<ClashPair> after, before;
    ClashStats s_now, s_then;
    MKTREE_RETURN_IF_ERROR(FocusedSelfClash(
        now, touched, o, [&](const ClashPair& p) { after.push_back(p); }, &s_now));
    MKTREE_RETURN_IF_ERROR(FocusedSelfClash(
        then, touched, o, [&](const ClashPair& p) { before.push_back(p); }, &s_then));
    AddClashStats(&total, s_now);
    AddClashStats(&total, s_then);
    auto key = [](const ClashPair& p) { return std::pair{p.a, p.b}; };
    std::set<std::pair<ObjectId, ObjectId>> had, has;
    for (const ClashPair& p : before) had.insert(key(p));
    for (const ClashPair& p : after) has.insert(key(p));
    uint64_t reported = 0, capped = 0;
    auto give = [&](const ClashPair& p, ClashChange c) {
      if (reported >= options.max_pairs) {
        ++capped;
        return;
      }
      ++reported;
      if (visit) visit(p, c);
    };
    for (const ClashPair& p : after)
      if (!had.count(key(p))) give(p, ClashChange::kNew);
    for (const ClashPair& p : before)
      if (!has.count(key(p))) give(p, ClashChange::kResolved);
    total.reported_pairs = reported;
    total.capped_pairs = capped;
    total.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return Status::Ok();
  });
}

}  // namespace mktree
