#include "engine/tree/build_memory.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace mktree::build {

void TrimHeap() {
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

}  // namespace mktree::build
