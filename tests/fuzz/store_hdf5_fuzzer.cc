// Fuzz target: opening an HDF5 store (StoreReader::Open through Database::Open) and querying it. The
// input is the file; the seeds are small valid stores, so the fuzzer mutates their bytes. HDF5's own
// parser is not ours and is not instrumented (Debian's libhdf5): this target checks that our layer
// (engine/store_format/hdf5_layout.cc, storage/hdf5_*) turns whatever HDF5 reads into an error or a correct
// store, and shows what libhdf5 itself does on damaged files. Kept apart from store_open so that crashes
// inside libhdf5 do not stop or crowd the campaign on our own paged-file parser.
#include <cstdint>
#include <vector>

#include "store_query_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  mktree::fuzz::OpenAndQuery(std::vector<uint8_t>(data, data + size), {}, /*named=*/true);
  return 0;
}
