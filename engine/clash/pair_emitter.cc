#include "engine/clash/pair_emitter.h"

#include "engine/clash/pair_rules.h"

namespace mktree::clash {

namespace {

constexpr size_t kKeptFoundCapacity = 16;

}  // namespace

void PairWork::Clear() {
  // A slot keeps no more than a typical leaf pair's pairs: each of a batch's slots would otherwise keep
  // the most it ever held, and two batches of slots are alive.
  if (found.capacity() > kKeptFoundCapacity) {
    std::vector<ClashPair>().swap(found);
  } else {
    found.clear();
  }
  candidates = excluded = 0;
  narrow = {};
}

void PairEmitter::Add(const PairWork& w) {
  s.candidate_pairs += w.candidates;
  s.excluded_pairs += w.excluded;
  s.bound_rejects += w.narrow.bound_rejects;
  s.triangle_tests += w.narrow.triangle_tests;
  s.containment_tests += w.narrow.containment_tests;
  s.hierarchies_built += w.narrow.hierarchies_built;
  s.classifiers_built += w.narrow.classifiers_built;
  for (const ClashPair& p : w.found) {
    CountClass(p, &s);
    if (p.cls == ClashClass::kTouch && !o.report_touch) {
      ++s.unreported_touches;
    } else if (s.reported_pairs >= o.max_pairs) {
      ++s.capped_pairs;
    } else {
      ++s.reported_pairs;
      if (visit) visit(p);
    }
  }
}

}  // namespace mktree::clash
