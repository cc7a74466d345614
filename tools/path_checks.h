// Checks of the files a command names, made before it does any work: inputs must be regular files (a FIFO
// would block the reader, a directory or device is no scene, store or query file), and an output must
// not be one of the inputs nor replace anything but a regular file.
#pragma once

#include <string>
#include <vector>

#include "mktree/status.h"

namespace mktree::tools {

// NotFound if `path` does not exist; InvalidArgument naming what it is if it is not a regular file (after
// symbolic links).
Status CheckInputFile(const std::string& path);

// InvalidArgument if `output` is empty, exists and is not a regular file, or is the same file as one of
// `inputs` (the same path, a hard link or a symbolic link to it). Inputs that do not exist are skipped.
Status CheckOutputFile(const std::string& output, const std::vector<std::string>& inputs);

}  // namespace mktree::tools
