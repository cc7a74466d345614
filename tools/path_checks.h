// The checks of the files a command names (storage/file_util.h), made before it does any work.
#pragma once

#include "storage/file_util.h"

namespace mktree::tools {

using storage_internal::CheckInputFile;
using storage_internal::CheckOutputFile;

}  // namespace mktree::tools
