// ClashOptions' exclusions over the objects of a clash's parts, by global id: the group names read from
// the parts' record pages when the options group objects by name. Thread safety: call from one thread;
// the Exclusions made are immutable (any number of threads may ask them).
#pragma once

#include <optional>

#include "engine/clash/pair_rules.h"
#include "engine/clash/part_numbering.h"
#include "mktree/clash.h"
#include "mktree/status.h"

namespace mktree::clash {

// The names of the visible objects (hidden ones are skipped: ClashPart::hidden) are read in global id
// order (each record page once) straight from the stores, not through their page caches, so that the
// clash's own page counts stay its leaves'; a damaged record page fails the run.
Status MakePartExclusions(const PartNumbering& parts, const ClashOptions& o, std::optional<Exclusions>* out);

}  // namespace mktree::clash
