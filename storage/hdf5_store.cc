#include "storage/store_backend.h"

namespace mktree {

Result<std::unique_ptr<StoreWriter::Impl>> CreateHdf5Writer(const std::string& temp_path, const BuildParams&) {
  return Status::Unsupported(temp_path + ": HDF5 backend not implemented yet");
}
Result<OpenedStore> OpenHdf5(const std::string& path, const ReadOptions&) {
  return Status::Unsupported(path + ": HDF5 backend not implemented yet");
}

}  // namespace mktree
