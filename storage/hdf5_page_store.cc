#include "storage/hdf5_page_store.h"

#include <algorithm>

namespace mktree {

using hdf5::ErrorText;
using hdf5::H5Id;

namespace {

constexpr const char* kPagesDataset = "pages";

H5Id PagesAccessList() {
  H5Id dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  // No HDF5 chunk cache: the engine's PageCache is the only cache.
  H5Pset_chunk_cache(dapl.get(), 0, 0, 1.0);
  return dapl;
}

}  // namespace

Result<std::unique_ptr<Hdf5PageStore>> Hdf5PageStore::Create(const std::string& path, uint64_t page_bytes,
                                                             FileOps& ops) {
  hdf5::Lock lock;
  auto created = hdf5::CreateWriterFile(path, ops);
  if (!created.ok()) return created.status();
  hdf5::WriterFile& w = created.value();
  hsize_t dims[2] = {0, page_bytes}, maxdims[2] = {H5S_UNLIMITED, page_bytes}, chunk[2] = {1, page_bytes};
  H5Id space(H5Screate_simple(2, dims, maxdims), H5Sclose);
  H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_chunk(dcpl.get(), 2, chunk);
  H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER);
  H5Id dapl = PagesAccessList();
  H5Id pages(
      H5Dcreate2(w.file.get(), kPagesDataset, H5T_STD_U8LE, space.get(), H5P_DEFAULT, dcpl.get(), dapl.get()),
      H5Dclose);
  if (!pages.ok() || w.io->failed()) {
    pages.reset();
    w.file.reset();
    if (w.io->failed()) return w.io->ToStatus();
    return Status::IOError(path + ": creating /pages: " + ErrorText());
  }
  return std::make_unique<Hdf5PageStore>(path, std::move(w.io), std::move(w.file), std::move(pages),
                                         page_bytes, 0);
}

Result<std::unique_ptr<Hdf5PageStore>> Hdf5PageStore::Open(const std::string& path, H5Id file,
                                                           uint64_t page_bytes, uint64_t page_count) {
  hdf5::Lock lock;
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };
  const hid_t f = file.get();
  H5Id dapl = PagesAccessList();
  if (H5Lexists(f, kPagesDataset, H5P_DEFAULT) <= 0) return bad("missing dataset pages");
  H5Id pages(H5Dopen2(f, kPagesDataset, dapl.get()), H5Dclose);
  if (!pages.ok()) return bad("pages: " + ErrorText());
  {
    H5Id space(H5Dget_space(pages.get()), H5Sclose);
    hsize_t dims[2] = {0, 0};
    if (H5Sget_simple_extent_ndims(space.get()) != 2 ||
        H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0 || dims[0] != page_count ||
        dims[1] != page_bytes)
      return bad("pages dataset has the wrong shape");
    H5Id dcpl(H5Dget_create_plist(pages.get()), H5Pclose);
    hsize_t chunk[2] = {0, 0};
    if (H5Pget_layout(dcpl.get()) != H5D_CHUNKED || H5Pget_chunk(dcpl.get(), 2, chunk) != 2 ||
        chunk[0] != 1 || chunk[1] != page_bytes || H5Pget_nfilters(dcpl.get()) != 0)
      return bad("pages dataset is not chunked one page per chunk without filters");
    // Walk the chunk index once (metadata only, no page is read).
    hsize_t chunks = 0;
    if (H5Dget_num_chunks(pages.get(), space.get(), &chunks) < 0 || chunks != page_count)
      return bad("pages chunk index damaged (" + std::to_string(chunks) + " chunks for " +
                 std::to_string(page_count) + " pages)");
  }
  H5Eclear2(H5E_DEFAULT);
  return std::make_unique<Hdf5PageStore>(path, nullptr, std::move(file), std::move(pages), page_bytes,
                                         page_count);
}

Hdf5PageStore::Hdf5PageStore(std::string name, std::unique_ptr<hdf5::WriterIo> io, H5Id file, H5Id pages,
                             uint64_t page_bytes, uint64_t count)
    : name_(std::move(name)),
      io_(std::move(io)),
      file_(std::move(file)),
      pages_(std::move(pages)),
      page_bytes_(page_bytes),
      count_(count),
      extent_(count) {}

// A destructor cannot report; writers call Close(true) and check it before this runs.
Hdf5PageStore::~Hdf5PageStore() { (void)Close(); }

Status Hdf5PageStore::ReadPage(uint64_t index, uint8_t* out) const {
  if (index >= count_) return PageOutOfRange(name_, index, count_);
  hdf5::Lock lock;
  const hsize_t offset[2] = {index, 0};
  hsize_t stored = 0;
  // Check the chunk's size first: H5Dread_chunk copies whatever size the file claims.
  if (H5Dget_chunk_storage_size(pages_.get(), offset, &stored) < 0 || stored != page_bytes_) {
    H5Eclear2(H5E_DEFAULT);
    return Status::Corruption(name_ + ": page " + std::to_string(index) +
                              ": chunk missing or of the wrong size (" + std::to_string(stored) + " bytes)");
  }
  uint32_t filters = 0;
  if (H5Dread_chunk(pages_.get(), H5P_DEFAULT, offset, &filters, out) < 0)
    return Status::IOError(name_ + ": page " + std::to_string(index) + ": " + ErrorText());
  if (filters != 0)
    return Status::Corruption(name_ + ": page " + std::to_string(index) + ": unexpected filter mask");
  return Status::Ok();
}

Status Hdf5PageStore::WritePage(uint64_t index, const uint8_t* data) {
  hdf5::Lock lock;  // also the count's and the extent's, for writes from two threads
  if (index >= extent_) {
    // Grow geometrically; chunks never written take no space, and Trim trims the extent.
    const hsize_t dims[2] = {std::max<hsize_t>(index + 1, 2 * extent_), page_bytes_};
    if (H5Dset_extent(pages_.get(), dims) < 0) return Failed("extending pages");
    extent_ = dims[0];
  }
  const hsize_t offset[2] = {index, 0};
  if (H5Dwrite_chunk(pages_.get(), H5P_DEFAULT, 0, offset, page_bytes_, data) < 0)
    return Failed("page " + std::to_string(index));
  MKTREE_RETURN_IF_ERROR(IoStatus());
  count_ = std::max(count_, index + 1);
  return Status::Ok();
}

Status Hdf5PageStore::Sync() {
  hdf5::Lock lock;
  if (H5Fflush(file_.get(), H5F_SCOPE_LOCAL) < 0) return Failed("flush");
  return IoStatus();
}

Status Hdf5PageStore::Trim() {
  hdf5::Lock lock;
  const hsize_t dims[2] = {count_, page_bytes_};
  if (extent_ != count_ && H5Dset_extent(pages_.get(), dims) < 0) return Failed("trimming pages");
  extent_ = count_;
  return IoStatus();
}

Status Hdf5PageStore::IoStatus() const { return io_ && io_->failed() ? io_->ToStatus() : Status::Ok(); }

Status Hdf5PageStore::Failed(const std::string& what) const {
  if (io_ && io_->failed()) {
    H5Eclear2(H5E_DEFAULT);
    return io_->ToStatus();
  }
  return Status::IOError(name_ + ": " + what + ": " + ErrorText());
}

Status Hdf5PageStore::Close(bool sync) {
  hdf5::Lock lock;
  if (io_) io_->sync_on_close = sync;
  pages_.reset();
  if (!file_.ok()) return IoStatus();
  if (H5Fclose(file_.release()) < 0) {
    // HDF5 1.10 keeps the identifier of a file whose close failed, over freed memory: never close it
    // again, and keep the driver's state alive for the library's own cleanup at exit.
    Status st = Failed("close");
    (void)io_.release();
    return st;
  }
  return IoStatus();
}

void Hdf5PageStore::Abort() {
  hdf5::Lock lock;
  if (io_) io_->discard = true;
  (void)Close();  // aborting: the file is discarded, a close error changes nothing
}

}  // namespace mktree
