// Hdf5PageStore: the pages of an HDF5 file as a PageStore. The dataset /pages is uint8
// [page_count x page_bytes], chunked one page per chunk, without filters; pages are written and read whole
// with H5Dwrite_chunk/H5Dread_chunk, which bypass HDF5's chunk cache (also turned off on the dataset): the
// engine's PageCache is the only one. A writer's file goes through the writer driver (storage/hdf5_file.h),
// so that an I/O error is reported once, as the system's error, and HDF5 always closes cleanly.
// Thread safety: as PageStore. Every HDF5 call takes the process-wide hdf5::Lock, so concurrent page reads
// are serialized.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "mktree/status.h"
#include "storage/file_ops.h"
#include "storage/hdf5_file.h"
#include "storage/page_store.h"

namespace mktree {

class Hdf5PageStore : public PageStore {
 public:
  // Creates `path` (through `ops`) with an empty /pages dataset of pages of `page_bytes`.
  static Result<std::unique_ptr<Hdf5PageStore>> Create(const std::string& path, uint64_t page_bytes,
                                                       FileOps& ops);
  // The pages of `file`, open for reading: /pages must have the shape [page_count x page_bytes], chunks of
  // one page without filters, and a chunk index that walks (metadata only; damage to it is refused here
  // rather than at the first page read). Errors are Corruption naming `path`.
  static Result<std::unique_ptr<Hdf5PageStore>> Open(const std::string& path, hdf5::H5Id file,
                                                     uint64_t page_bytes, uint64_t page_count);

  // `io` is the writer's driver state (null for a reader); it must outlive the file.
  Hdf5PageStore(std::string name, std::unique_ptr<hdf5::WriterIo> io, hdf5::H5Id file, hdf5::H5Id pages,
                uint64_t page_bytes, uint64_t count);
  ~Hdf5PageStore() override;

  uint64_t page_bytes() const override { return page_bytes_; }
  uint64_t page_count() const override { return count_; }
  const std::string& name() const override { return name_; }
  Status ReadPage(uint64_t index, uint8_t* out) const override;
  Status WritePage(uint64_t index, const uint8_t* data) override;
  Status Sync() override;

  // The file, for what else the caller keeps in it.
  hid_t file() const { return file_.get(); }
  // Trims the dataset's extent to the pages written (writer).
  Status Trim();
  // The writer's first I/O error, if any (the driver hides it from HDF5).
  Status IoStatus() const;
  // Closes the file; with `sync`, fsyncs it first (the writer's last step). Every HDF5 identifier of the
  // file is released, and the first I/O error of the whole write is reported.
  Status Close(bool sync = false);
  // Stops writing (the file is being thrown away) and closes it.
  void Abort();

 private:
  // An HDF5 call failed while doing `what`: the I/O error behind it if there was one, else HDF5's message.
  Status Failed(const std::string& what) const;

  std::string name_;
  std::unique_ptr<hdf5::WriterIo> io_;
  hdf5::H5Id file_, pages_;
  uint64_t page_bytes_, count_;
  hsize_t extent_;
};

}  // namespace mktree
