// What a run of clash tests found, keyed, compared and grouped: the model the workflow's outputs read.
// The types are public (include/mktree/clash_issues.h: RunClashTests hands a ClashRun to programs and to
// Python); this header is where the engine's outputs (engine/report/) take them from.
#pragma once

#include "mktree/clash_issues.h"
