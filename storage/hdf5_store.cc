// The HDF5 backend (layout in docs/store_format.md). One file:
//   /pages               uint8 [page_count x MemPage], chunked one page per chunk, no filters; pages are
//                        written and read whole with H5Dwrite_chunk/H5Dread_chunk, which bypass HDF5's
//                        chunk cache (also turned off on the dataset) so the engine's PageCache is the only one
//   /tree/nodes, /tree/split_nodes, /tree/leaves   compound datasets with named fields
//   /objects             compound (id, leaf, name as a fixed-length NUL-padded string)
//   /stats_json          scalar fixed-length string
//   attributes on /      magic "MKTREE-HDF5" (written last), format_version, build parameters, codec, counts,
//                        and XXH3-64 checksums of the canonical encodings (tree_codec.h) of each part
// HDF5 is not thread-safe in Debian's serial build: every HDF5 call in this file runs under one
// process-wide mutex, so concurrent page reads from an HDF5 store are serialized.
#include <fcntl.h>
#include <hdf5.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstring>
#include <memory>
#include <mutex>

#include "storage/byte_io.h"
#include "storage/file_util.h"
#include "storage/store_backend.h"

namespace mktree {

namespace {

constexpr const char* kHdf5Magic = "MKTREE-HDF5";
constexpr uint32_t kHdf5FormatVersion = 2;  // 2: the leaf filter holds 10-bit levels in 8 bytes an object
constexpr hsize_t kObjectChunkRows = 8192;

std::recursive_mutex& Hdf5Mutex() {
  static std::recursive_mutex mu;
  return mu;
}

// Owns one HDF5 identifier; closes it with the matching H5?close.
class H5Id {
 public:
  H5Id() = default;
  H5Id(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  H5Id(H5Id&& o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = -1; }
  H5Id& operator=(H5Id&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = o.id_;
      close_ = o.close_;
      o.id_ = -1;
    }
    return *this;
  }
  ~H5Id() { reset(); }
  void reset() {
    if (id_ >= 0 && close_) close_(id_);
    id_ = -1;
  }
  // Gives up ownership without closing.
  hid_t release() {
    const hid_t id = id_;
    id_ = -1;
    return id;
  }
  hid_t get() const { return id_; }
  bool ok() const { return id_ >= 0; }

 private:
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

// The innermost message of HDF5's current error stack (e.g. "truncated file: eof = ..."), for errors.
std::string Hdf5ErrorText() {
  std::string msg;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned n, const H5E_error2_t* e, void* data) -> herr_t {
        if (n == 0 && e->desc) *static_cast<std::string*>(data) = e->desc;
        return 0;
      },
      &msg);
  H5Eclear2(H5E_DEFAULT);
  return msg.empty() ? "HDF5 error" : msg;
}

void QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

// In-memory records for the compound datasets.
struct NodeRec {
  float box_min[3], box_max[3];
  float a, b;
  uint32_t child[2];
  uint32_t leaf, split_root;
  uint8_t axis, depth;
};
struct SplitRec {
  float cut;
  uint32_t child[2];
  uint8_t axis;
  uint8_t label;
};
struct LeafRec {
  float box_min[3], box_max[3];
  uint32_t node, object_count;
  uint64_t payload_bytes, first_page;
  uint32_t page_count;
};

// Builds a compound type from fields; `packed` gives the file type (fields back to back, little-endian),
// otherwise the memory type (struct offsets, native types).
struct Field {
  const char* name;
  size_t offset;
  hid_t mem;   // native type
  hid_t file;  // little-endian type
  int array = 0;  // > 0: an array of that many elements
};

H5Id MakeCompound(const std::vector<Field>& fields, size_t struct_size, bool packed) {
  size_t total = 0;
  std::vector<H5Id> members;
  for (const Field& f : fields) {
    hid_t base = packed ? f.file : f.mem;
    if (f.array > 0) {
      hsize_t n = static_cast<hsize_t>(f.array);
      members.emplace_back(H5Tarray_create2(base, 1, &n), H5Tclose);
    } else {
      members.emplace_back(H5Tcopy(base), H5Tclose);
    }
    total += H5Tget_size(members.back().get());
  }
  H5Id t(H5Tcreate(H5T_COMPOUND, packed ? total : struct_size), H5Tclose);
  size_t off = 0;
  for (size_t i = 0; i < fields.size(); ++i) {
    H5Tinsert(t.get(), fields[i].name, packed ? off : fields[i].offset, members[i].get());
    off += H5Tget_size(members[i].get());
  }
  return t;
}

H5Id LabelType(bool native) {
  H5Id t(H5Tenum_create(native ? H5T_NATIVE_UINT8 : H5T_STD_U8LE), H5Tclose);
  const char* names[] = {"EMPTY", "LEFT", "RIGHT", "BOTH"};
  for (uint8_t v = 0; v < 4; ++v) H5Tenum_insert(t.get(), names[v], &v);
  return t;
}

std::vector<Field> NodeFields() {
  return {{"box_min", offsetof(NodeRec, box_min), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, 3},
          {"box_max", offsetof(NodeRec, box_max), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, 3},
          {"a", offsetof(NodeRec, a), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE},
          {"b", offsetof(NodeRec, b), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE},
          {"child", offsetof(NodeRec, child), H5T_NATIVE_UINT32, H5T_STD_U32LE, 2},
          {"leaf", offsetof(NodeRec, leaf), H5T_NATIVE_UINT32, H5T_STD_U32LE},
          {"split_root", offsetof(NodeRec, split_root), H5T_NATIVE_UINT32, H5T_STD_U32LE},
          {"axis", offsetof(NodeRec, axis), H5T_NATIVE_UINT8, H5T_STD_U8LE},
          {"depth", offsetof(NodeRec, depth), H5T_NATIVE_UINT8, H5T_STD_U8LE}};
}
std::vector<Field> LeafFields() {
  return {{"box_min", offsetof(LeafRec, box_min), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, 3},
          {"box_max", offsetof(LeafRec, box_max), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, 3},
          {"node", offsetof(LeafRec, node), H5T_NATIVE_UINT32, H5T_STD_U32LE},
          {"object_count", offsetof(LeafRec, object_count), H5T_NATIVE_UINT32, H5T_STD_U32LE},
          {"payload_bytes", offsetof(LeafRec, payload_bytes), H5T_NATIVE_UINT64, H5T_STD_U64LE},
          {"first_page", offsetof(LeafRec, first_page), H5T_NATIVE_UINT64, H5T_STD_U64LE},
          {"page_count", offsetof(LeafRec, page_count), H5T_NATIVE_UINT32, H5T_STD_U32LE}};
}
H5Id SplitType(bool packed) {
  H5Id label = LabelType(!packed);
  std::vector<Field> f = {{"cut", offsetof(SplitRec, cut), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE},
                          {"child", offsetof(SplitRec, child), H5T_NATIVE_UINT32, H5T_STD_U32LE, 2},
                          {"axis", offsetof(SplitRec, axis), H5T_NATIVE_UINT8, H5T_STD_U8LE},
                          {"label", offsetof(SplitRec, label), label.get(), label.get()}};
  return MakeCompound(f, sizeof(SplitRec), packed);
}

NodeRec ToRec(const TreeNode& n) {
  NodeRec r{};
  for (int i = 0; i < 3; ++i) {
    r.box_min[i] = n.box.min[i];
    r.box_max[i] = n.box.max[i];
  }
  r.a = n.a;
  r.b = n.b;
  r.child[0] = n.child[0];
  r.child[1] = n.child[1];
  r.leaf = n.leaf;
  r.split_root = n.split_root;
  r.axis = n.axis;
  r.depth = n.depth;
  return r;
}
TreeNode FromRec(const NodeRec& r) {
  TreeNode n;
  for (int i = 0; i < 3; ++i) {
    n.box.min[i] = r.box_min[i];
    n.box.max[i] = r.box_max[i];
  }
  n.a = r.a;
  n.b = r.b;
  n.child[0] = r.child[0];
  n.child[1] = r.child[1];
  n.leaf = r.leaf;
  n.split_root = r.split_root;
  n.axis = r.axis;
  n.depth = r.depth;
  return n;
}
LeafRec ToRec(const LeafInfo& l) {
  LeafRec r{};
  for (int i = 0; i < 3; ++i) {
    r.box_min[i] = l.box.min[i];
    r.box_max[i] = l.box.max[i];
  }
  r.node = l.node;
  r.object_count = l.object_count;
  r.payload_bytes = l.payload_bytes;
  r.first_page = l.first_page;
  r.page_count = l.page_count;
  return r;
}
LeafInfo FromRec(const LeafRec& r) {
  LeafInfo l;
  for (int i = 0; i < 3; ++i) {
    l.box.min[i] = r.box_min[i];
    l.box.max[i] = r.box_max[i];
  }
  l.node = r.node;
  l.object_count = r.object_count;
  l.payload_bytes = r.payload_bytes;
  l.first_page = r.first_page;
  l.page_count = r.page_count;
  return l;
}

constexpr int kChecksumCount = 7;

// Writes a 1-D contiguous compound dataset.
Status WriteTable(hid_t loc, const char* name, hid_t file_type, hid_t mem_type, const void* data, size_t n,
                  const std::string& path) {
  hsize_t dims[1] = {n};
  H5Id space(H5Screate_simple(1, dims, nullptr), H5Sclose);
  H5Id d(H5Dcreate2(loc, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
  if (!d.ok() || (n > 0 && H5Dwrite(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0))
    return Status::IOError(path + ": writing " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}

// Reads a 1-D compound dataset into `out` (resized to its length).
template <typename Rec>
Status ReadTable(hid_t loc, const char* name, hid_t mem_type, std::vector<Rec>* out, const std::string& path) {
  H5Id d(H5Dopen2(loc, name, H5P_DEFAULT), H5Dclose);
  if (!d.ok()) return Status::Corruption(path + ": missing dataset " + name);
  H5Id space(H5Dget_space(d.get()), H5Sclose);
  hsize_t dims[1] = {0};
  if (H5Sget_simple_extent_ndims(space.get()) != 1 || H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0)
    return Status::Corruption(path + ": dataset " + name + " is not 1-D");
  out->resize(dims[0]);
  if (dims[0] > 0 && H5Dread(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out->data()) < 0)
    return Status::Corruption(path + ": reading " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}

template <typename T>
Status WriteAttr(hid_t loc, const char* name, hid_t file_type, hid_t mem_type, const T& v, const std::string& path) {
  H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
  H5Id a(H5Acreate2(loc, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.ok() || H5Awrite(a.get(), mem_type, &v) < 0)
    return Status::IOError(path + ": writing attribute " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}
template <typename T>
Status ReadAttr(hid_t loc, const char* name, hid_t mem_type, T* v, const std::string& path) {
  if (H5Aexists(loc, name) <= 0) return Status::Corruption(path + ": missing attribute " + name);
  H5Id a(H5Aopen(loc, name, H5P_DEFAULT), H5Aclose);
  if (!a.ok() || H5Aread(a.get(), mem_type, v) < 0)
    return Status::Corruption(path + ": reading attribute " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}
H5Id StringType(size_t size) {
  H5Id t(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(t.get(), size);
  H5Tset_strpad(t.get(), H5T_STR_NULLPAD);
  return t;
}
Status WriteStringAttr(hid_t loc, const char* name, const std::string& s, const std::string& path) {
  H5Id t = StringType(std::max<size_t>(1, s.size()));
  H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
  H5Id a(H5Acreate2(loc, name, t.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  std::string padded = s;
  padded.resize(std::max<size_t>(1, s.size()), '\0');
  if (!a.ok() || H5Awrite(a.get(), t.get(), padded.data()) < 0)
    return Status::IOError(path + ": writing attribute " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}
Result<std::string> ReadStringAttr(hid_t loc, const char* name, const std::string& path) {
  if (H5Aexists(loc, name) <= 0) return Status::Corruption(path + ": missing attribute " + name);
  H5Id a(H5Aopen(loc, name, H5P_DEFAULT), H5Aclose);
  H5Id t(H5Aget_type(a.get()), H5Tclose);
  if (!t.ok() || H5Tget_class(t.get()) != H5T_STRING || H5Tis_variable_str(t.get()) > 0)
    return Status::Corruption(path + ": attribute " + name + " is not a fixed-length string");
  const size_t n = H5Tget_size(t.get());
  std::string s(n, '\0');
  if (H5Aread(a.get(), t.get(), s.data()) < 0)
    return Status::Corruption(path + ": reading attribute " + name + ": " + Hdf5ErrorText());
  s.resize(std::strlen(s.c_str()));
  return s;
}

// XXH3 of the header fields: parameters, codec, counts, version.
uint64_t HeaderChecksum(const BuildParams& p, const CodecOptions& c, uint64_t pages, uint64_t objects) {
  std::vector<uint8_t> b = EncodeParams(p, c);
  storage_internal::ByteWriter w(&b);
  w.Put<uint64_t>(pages);
  w.Put<uint64_t>(objects);
  w.Put<uint32_t>(kHdf5FormatVersion);
  return Checksum(b);
}
// XXH3 of the object leaves, name ends and names concatenated, streamed part by part (the same value,
// without a copy of the whole table).
uint64_t ObjectsChecksum(const ObjectTable& t) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), XXH3_freeState);
  XXH3_64bits_reset(state.get());
  {
    const std::vector<uint8_t> b = EncodeObjectLeaves(t);
    XXH3_64bits_update(state.get(), b.data(), b.size());
  }
  {
    const std::vector<uint8_t> b = EncodeObjectNameEnds(t);
    XXH3_64bits_update(state.get(), b.data(), b.size());
  }
  XXH3_64bits_update(state.get(), t.names.data(), t.names.size());
  return XXH3_64bits_digest(state.get());
}

class Hdf5PageStore : public PageStore {
 public:
  Hdf5PageStore(std::string name, H5Id file, H5Id pages, uint64_t mem_page, uint64_t count)
      : name_(std::move(name)), file_(std::move(file)), pages_(std::move(pages)), mem_page_(mem_page), count_(count),
        extent_(count) {}
  ~Hdf5PageStore() override { Close(); }

  uint64_t page_bytes() const override { return mem_page_; }
  uint64_t page_count() const override { return count_; }
  const std::string& name() const override { return name_; }

  Status ReadPage(uint64_t index, uint8_t* out) const override {
    if (index >= count_)
      return PageOutOfRange(name_, index, count_);
    std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
    const hsize_t offset[2] = {index, 0};
    hsize_t stored = 0;
    // Check the chunk's size first: H5Dread_chunk copies whatever size the file claims.
    if (H5Dget_chunk_storage_size(pages_.get(), offset, &stored) < 0 || stored != mem_page_)
      return Status::Corruption(name_ + ": page " + std::to_string(index) + ": chunk missing or of the wrong size (" +
                                std::to_string(stored) + " bytes)");
    uint32_t filters = 0;
    if (H5Dread_chunk(pages_.get(), H5P_DEFAULT, offset, &filters, out) < 0)
      return Status::IOError(name_ + ": page " + std::to_string(index) + ": " + Hdf5ErrorText());
    if (filters != 0) return Status::Corruption(name_ + ": page " + std::to_string(index) + ": unexpected filter mask");
    return Status::Ok();
  }

  Status WritePage(uint64_t index, const uint8_t* data) override {
    if (index > count_)
      return Status::InvalidArgument(name_ + ": page " + std::to_string(index) + " written out of order");
    std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
    if (index >= extent_) {
      // Grow geometrically; chunks never written take no space, and Finish trims the extent.
      const hsize_t dims[2] = {std::max<hsize_t>(index + 1, 2 * extent_), mem_page_};
      if (H5Dset_extent(pages_.get(), dims) < 0)
        return Status::IOError(name_ + ": extending pages: " + Hdf5ErrorText());
      extent_ = dims[0];
    }
    const hsize_t offset[2] = {index, 0};
    if (H5Dwrite_chunk(pages_.get(), H5P_DEFAULT, 0, offset, mem_page_, data) < 0)
      return Status::IOError(name_ + ": page " + std::to_string(index) + ": " + Hdf5ErrorText());
    if (index == count_) ++count_;
    return Status::Ok();
  }

  Status Sync() override {
    std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
    if (H5Fflush(file_.get(), H5F_SCOPE_LOCAL) < 0) return Status::IOError(name_ + ": flush: " + Hdf5ErrorText());
    return Status::Ok();
  }

  // Trims the extent to the pages written (writer).
  Status Trim() {
    const hsize_t dims[2] = {count_, mem_page_};
    if (extent_ != count_ && H5Dset_extent(pages_.get(), dims) < 0)
      return Status::IOError(name_ + ": trimming pages: " + Hdf5ErrorText());
    extent_ = count_;
    return Status::Ok();
  }
  hid_t file() const { return file_.get(); }
  Status Close() {
    std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
    pages_.reset();
    // The id is spent even when H5Fclose fails: closing it again is a double close.
    if (file_.ok() && H5Fclose(file_.release()) < 0)
      return Status::IOError(name_ + ": close: " + Hdf5ErrorText());
    return Status::Ok();
  }

 private:
  std::string name_;
  H5Id file_, pages_;
  uint64_t mem_page_, count_;
  hsize_t extent_;
};

class Hdf5Writer : public StoreWriter::Impl {
 public:
  Hdf5Writer(std::string path, std::unique_ptr<Hdf5PageStore> store) : path_(std::move(path)), store_(std::move(store)) {}
  PageStore& pages() override { return *store_; }
  void Abort() override { store_->Close(); }

  Status Finish(const StoreContents& c) override {
    {
      std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
      MKTREE_RETURN_IF_ERROR(WriteAll(c));
    }
    MKTREE_RETURN_IF_ERROR(store_->Close());
    // HDF5 does not fsync: do it ourselves before the rename.
    const int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return Status::IOError(path_ + ": open for fsync: " + storage_internal::ErrnoText(errno));
    const int r = ::fsync(fd);
    const int err = errno;
    ::close(fd);
    if (r != 0) return Status::IOError(path_ + ": fsync: " + storage_internal::ErrnoText(err));
    return Status::Ok();
  }

 private:
  Status WriteAll(const StoreContents& c) {
    const hid_t f = store_->file();
    MKTREE_RETURN_IF_ERROR(store_->Trim());
    H5Id tree(H5Gcreate2(f, "tree", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    if (!tree.ok()) return Status::IOError(path_ + ": creating /tree: " + Hdf5ErrorText());

    // Each table's records are converted, written and freed in turn (they copy the tree, in RAM already).
    auto write_table = [&](const char* name, const auto& items, auto to_rec, const H5Id& file_type,
                           const H5Id& mem_type) {
      std::vector<decltype(to_rec(items.front()))> recs;
      recs.reserve(items.size());
      for (const auto& x : items) recs.push_back(to_rec(x));
      return WriteTable(tree.get(), name, file_type.get(), mem_type.get(), recs.data(), recs.size(), path_);
    };
    MKTREE_RETURN_IF_ERROR(write_table(
        "nodes", c.tree.nodes, [](const TreeNode& n) { return ToRec(n); },
        MakeCompound(NodeFields(), sizeof(NodeRec), true), MakeCompound(NodeFields(), sizeof(NodeRec), false)));
    MKTREE_RETURN_IF_ERROR(write_table(
        "split_nodes", c.tree.split_nodes,
        [](const SplitNode& n) { return SplitRec{n.cut, {n.child[0], n.child[1]}, n.axis, static_cast<uint8_t>(n.label)}; },
        SplitType(true), SplitType(false)));
    MKTREE_RETURN_IF_ERROR(write_table(
        "leaves", c.tree.leaves, [](const LeafInfo& l) { return ToRec(l); },
        MakeCompound(LeafFields(), sizeof(LeafRec), true), MakeCompound(LeafFields(), sizeof(LeafRec), false)));
    // The leaf filter: 6 uint8 per object (quantized min x y z, max x y z), leaf by leaf.
    MKTREE_RETURN_IF_ERROR(WriteTable(tree.get(), "leaf_filter", H5T_STD_U8LE, H5T_NATIVE_UINT8,
                                      c.tree.leaf_filter.data(), c.tree.leaf_filter.size(), path_));

    MKTREE_RETURN_IF_ERROR(WriteObjects(f, c.objects));

    {  // stats JSON: a scalar fixed-length string dataset. Not variable-length: HDF5's global heap, where
       // those live, has no checksum, and a damaged heap entry crashes the library on read.
      const std::string& js = c.stats_json;
      H5Id t = StringType(std::max<size_t>(1, js.size()));
      H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
      H5Id d(H5Dcreate2(f, "stats_json", t.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
      std::string padded = js;
      padded.resize(std::max<size_t>(1, js.size()), '\0');
      if (!d.ok() || H5Dwrite(d.get(), t.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, padded.data()) < 0)
        return Status::IOError(path_ + ": writing stats_json: " + Hdf5ErrorText());
    }

    const uint64_t pages = store_->page_count(), objects = c.objects.size();
    const int32_t level = c.codec.zstd_level;
    const uint8_t shuffle = c.codec.shuffle ? 1 : 0;
    // One encoded section alive at a time (an initializer list would keep every temporary to its end).
    uint64_t sums[kChecksumCount];
    sums[0] = HeaderChecksum(c.params, c.codec, pages, objects);
    sums[1] = Checksum(EncodeNodes(c.tree.nodes));
    sums[2] = Checksum(EncodeSplitNodes(c.tree.split_nodes));
    sums[3] = Checksum(EncodeLeaves(c.tree.leaves));
    sums[4] = ObjectsChecksum(c.objects);
    sums[5] = Checksum(c.stats_json);
    sums[6] = Checksum(c.tree.leaf_filter);
    const char* sum_names[kChecksumCount] = {"checksum_header",  "checksum_nodes",      "checksum_split_nodes",
                                             "checksum_leaves",  "checksum_objects",    "checksum_stats_json",
                                             "checksum_leaf_filter"};
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "format_version", H5T_STD_U32LE, H5T_NATIVE_UINT32, kHdf5FormatVersion, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "block_size", H5T_STD_U32LE, H5T_NATIVE_UINT32, c.params.block_size, path_));
    MKTREE_RETURN_IF_ERROR(
        WriteAttr(f, "blocks_per_page", H5T_STD_U32LE, H5T_NATIVE_UINT32, c.params.blocks_per_page, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "balance_r", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, c.params.balance_r, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "split_tree_node_budget", H5T_STD_U32LE, H5T_NATIVE_UINT32,
                                     c.params.split_tree_node_budget, path_));
    MKTREE_RETURN_IF_ERROR(WriteStringAttr(f, "codec", c.codec.codec == Codec::kZstd ? "zstd" : "none", path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "zstd_level", H5T_STD_I32LE, H5T_NATIVE_INT32, level, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "shuffle", H5T_STD_U8LE, H5T_NATIVE_UINT8, shuffle, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "page_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, pages, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "object_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, objects, path_));
    for (int i = 0; i < kChecksumCount; ++i)
      MKTREE_RETURN_IF_ERROR(WriteAttr(f, sum_names[i], H5T_STD_U64LE, H5T_NATIVE_UINT64, sums[i], path_));
    // Last: the magic that makes the file a store.
    MKTREE_RETURN_IF_ERROR(WriteStringAttr(f, "magic", kHdf5Magic, path_));
    if (H5Fflush(f, H5F_SCOPE_LOCAL) < 0) return Status::IOError(path_ + ": flush: " + Hdf5ErrorText());
    return Status::Ok();
  }

  // /objects: (id, leaf, name) rows, written in blocks so that the buffer stays small.
  Status WriteObjects(hid_t f, const ObjectTable& t) {
    size_t width = 1;
    for (uint64_t i = 0; i < t.size(); ++i) width = std::max(width, t.name(i).size());
    const size_t row = 8 + width;
    H5Id name_type = StringType(width);
    H5Id mem(H5Tcreate(H5T_COMPOUND, row), H5Tclose);
    H5Tinsert(mem.get(), "id", 0, H5T_NATIVE_UINT32);
    H5Tinsert(mem.get(), "leaf", 4, H5T_NATIVE_UINT32);
    H5Tinsert(mem.get(), "name", 8, name_type.get());
    H5Id file(H5Tcreate(H5T_COMPOUND, row), H5Tclose);
    H5Tinsert(file.get(), "id", 0, H5T_STD_U32LE);
    H5Tinsert(file.get(), "leaf", 4, H5T_STD_U32LE);
    H5Tinsert(file.get(), "name", 8, name_type.get());

    const hsize_t n = t.size();
    hsize_t dims[1] = {n}, maxdims[1] = {H5S_UNLIMITED}, chunk[1] = {std::clamp<hsize_t>(n, 1, kObjectChunkRows)};
    H5Id space(H5Screate_simple(1, dims, maxdims), H5Sclose);
    H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    H5Pset_chunk(dcpl.get(), 1, chunk);
    // Metadata, not pages: let HDF5 compress it (names pad to the longest one).
    if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) > 0) {
      H5Pset_shuffle(dcpl.get());
      H5Pset_deflate(dcpl.get(), 4);
    }
    H5Id d(H5Dcreate2(f, "objects", file.get(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose);
    if (!d.ok()) return Status::IOError(path_ + ": creating /objects: " + Hdf5ErrorText());
    std::vector<uint8_t> buf;
    for (hsize_t start = 0; start < n; start += kObjectChunkRows) {
      const hsize_t count = std::min<hsize_t>(kObjectChunkRows, n - start);
      buf.assign(count * row, 0);
      for (hsize_t i = 0; i < count; ++i) {
        uint8_t* r = buf.data() + i * row;
        storage_internal::Put<uint32_t>(r, static_cast<uint32_t>(start + i));
        storage_internal::Put<uint32_t>(r + 4, t.leaf[start + i]);
        const std::string_view name = t.name(start + i);
        std::memcpy(r + 8, name.data(), name.size());
      }
      H5Id fspace(H5Dget_space(d.get()), H5Sclose);
      hsize_t s[1] = {start}, c[1] = {count};
      H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, s, nullptr, c, nullptr);
      H5Id mspace(H5Screate_simple(1, c, nullptr), H5Sclose);
      if (H5Dwrite(d.get(), mem.get(), mspace.get(), fspace.get(), H5P_DEFAULT, buf.data()) < 0)
        return Status::IOError(path_ + ": writing /objects: " + Hdf5ErrorText());
    }
    return Status::Ok();
  }

  std::string path_;
  std::unique_ptr<Hdf5PageStore> store_;
};

H5Id PagesAccessList() {
  H5Id dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  // No HDF5 chunk cache: the engine's PageCache is the only cache.
  H5Pset_chunk_cache(dapl.get(), 0, 0, 1.0);
  return dapl;
}

Status ReadObjects(hid_t f, uint64_t expected, ObjectTable* t, const std::string& path) {
  H5Id d(H5Dopen2(f, "objects", H5P_DEFAULT), H5Dclose);
  if (!d.ok()) return Status::Corruption(path + ": missing dataset objects");
  H5Id ftype(H5Dget_type(d.get()), H5Tclose);
  const int name_idx = H5Tget_member_index(ftype.get(), "name");
  if (H5Tget_class(ftype.get()) != H5T_COMPOUND || name_idx < 0)
    return Status::Corruption(path + ": objects is not an (id, leaf, name) table");
  H5Id ntype(H5Tget_member_type(ftype.get(), static_cast<unsigned>(name_idx)), H5Tclose);
  if (H5Tget_class(ntype.get()) != H5T_STRING || H5Tis_variable_str(ntype.get()) > 0)
    return Status::Corruption(path + ": objects.name is not a fixed-length string");
  const size_t width = H5Tget_size(ntype.get()), row = 8 + width;
  H5Id name_type = StringType(width);
  H5Id mem(H5Tcreate(H5T_COMPOUND, row), H5Tclose);
  H5Tinsert(mem.get(), "id", 0, H5T_NATIVE_UINT32);
  H5Tinsert(mem.get(), "leaf", 4, H5T_NATIVE_UINT32);
  H5Tinsert(mem.get(), "name", 8, name_type.get());
  H5Id fspace(H5Dget_space(d.get()), H5Sclose);
  hsize_t dims[1] = {0};
  if (H5Sget_simple_extent_ndims(fspace.get()) != 1 || H5Sget_simple_extent_dims(fspace.get(), dims, nullptr) < 0 ||
      dims[0] != expected)
    return Status::Corruption(path + ": objects table has the wrong size");
  std::vector<uint8_t> buf;
  for (hsize_t start = 0; start < dims[0]; start += kObjectChunkRows) {
    const hsize_t count = std::min<hsize_t>(kObjectChunkRows, dims[0] - start);
    buf.assign(count * row, 0);
    hsize_t s[1] = {start}, c[1] = {count};
    H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, s, nullptr, c, nullptr);
    H5Id mspace(H5Screate_simple(1, c, nullptr), H5Sclose);
    if (H5Dread(d.get(), mem.get(), mspace.get(), fspace.get(), H5P_DEFAULT, buf.data()) < 0)
      return Status::Corruption(path + ": reading objects: " + Hdf5ErrorText());
    for (hsize_t i = 0; i < count; ++i) {
      const uint8_t* r = buf.data() + i * row;
      if (storage_internal::Get<uint32_t>(r) != start + i)
        return Status::Corruption(path + ": objects row " + std::to_string(start + i) + " has the wrong id");
      const char* name = reinterpret_cast<const char*>(r + 8);
      t->Append(storage_internal::Get<uint32_t>(r + 4), std::string_view(name, strnlen(name, width)));
    }
  }
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<StoreWriter::Impl>> CreateHdf5Writer(const std::string& temp_path, const BuildParams& params) {
  std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
  QuietHdf5();
  H5Id fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  // The 1.10 format: checksummed object headers and chunk indexes.
  H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V110, H5F_LIBVER_LATEST);
  H5Id file(H5Fcreate(temp_path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), H5Fclose);
  if (!file.ok()) return Status::IOError(temp_path + ": create: " + Hdf5ErrorText());
  const uint64_t mem_page = params.mem_page();
  hsize_t dims[2] = {0, mem_page}, maxdims[2] = {H5S_UNLIMITED, mem_page}, chunk[2] = {1, mem_page};
  H5Id space(H5Screate_simple(2, dims, maxdims), H5Sclose);
  H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_chunk(dcpl.get(), 2, chunk);
  H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER);
  H5Id dapl = PagesAccessList();
  H5Id pages(H5Dcreate2(file.get(), "pages", H5T_STD_U8LE, space.get(), H5P_DEFAULT, dcpl.get(), dapl.get()), H5Dclose);
  if (!pages.ok()) return Status::IOError(temp_path + ": creating /pages: " + Hdf5ErrorText());
  auto store = std::make_unique<Hdf5PageStore>(temp_path, std::move(file), std::move(pages), mem_page, 0);
  return std::unique_ptr<StoreWriter::Impl>(new Hdf5Writer(temp_path, std::move(store)));
}

Result<OpenedStore> OpenHdf5(const std::string& path, const ReadOptions& opts) {
  std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
  QuietHdf5();
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };
  H5Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) return bad("HDF5 cannot open it (" + Hdf5ErrorText() + "): truncated or damaged");
  const hid_t f = file.get();
  if (H5Aexists(f, "magic") <= 0) return bad("an HDF5 file, but not an mktree store (no magic attribute)");
  auto magic = ReadStringAttr(f, "magic", path);
  if (!magic.ok()) return magic.status();
  if (*magic != kHdf5Magic) return bad("an HDF5 file, but not an mktree store (magic \"" + *magic + "\")");
  uint32_t version = 0;
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "format_version", H5T_NATIVE_UINT32, &version, path));
  if (version != kHdf5FormatVersion)
    return storage_internal::UnsupportedFormatVersion(path, "HDF5 store", version, kHdf5FormatVersion);
  OpenedStore out;
  StoreContents& c = out.contents;
  uint64_t page_count = 0, object_count = 0;
  int32_t level = 0;
  uint8_t shuffle = 0;
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "block_size", H5T_NATIVE_UINT32, &c.params.block_size, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "blocks_per_page", H5T_NATIVE_UINT32, &c.params.blocks_per_page, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "balance_r", H5T_NATIVE_DOUBLE, &c.params.balance_r, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "split_tree_node_budget", H5T_NATIVE_UINT32, &c.params.split_tree_node_budget, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "zstd_level", H5T_NATIVE_INT32, &level, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "shuffle", H5T_NATIVE_UINT8, &shuffle, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "page_count", H5T_NATIVE_UINT64, &page_count, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "object_count", H5T_NATIVE_UINT64, &object_count, path));
  auto codec = ReadStringAttr(f, "codec", path);
  if (!codec.ok()) return codec.status();
  if (*codec != "zstd" && *codec != "none") return bad("unknown codec \"" + *codec + "\"");
  c.codec.codec = *codec == "zstd" ? Codec::kZstd : Codec::kNone;
  c.codec.zstd_level = level;
  c.codec.shuffle = shuffle != 0;
  const char* sum_names[kChecksumCount] = {"checksum_header",  "checksum_nodes",      "checksum_split_nodes",
                                           "checksum_leaves",  "checksum_objects",    "checksum_stats_json",
                                           "checksum_leaf_filter"};
  uint64_t sums[kChecksumCount];
  for (int i = 0; i < kChecksumCount; ++i) MKTREE_RETURN_IF_ERROR(ReadAttr(f, sum_names[i], H5T_NATIVE_UINT64, &sums[i], path));
  if (HeaderChecksum(c.params, c.codec, page_count, object_count) != sums[0]) return bad("header checksum mismatch");
  BuildParams check_params;
  CodecOptions check_codec;
  Status st = DecodeParams(EncodeParams(c.params, c.codec), &check_params, &check_codec);
  if (!st.ok()) return bad(st.message());
  const uint64_t mem_page = c.params.mem_page();

  // The tree.
  H5Id tree(H5Gopen2(f, "tree", H5P_DEFAULT), H5Gclose);
  if (!tree.ok()) return bad("missing group /tree");
  std::vector<NodeRec> nodes;
  std::vector<SplitRec> splits;
  std::vector<LeafRec> leaves;
  H5Id node_mem = MakeCompound(NodeFields(), sizeof(NodeRec), false);
  H5Id split_mem = SplitType(false);
  H5Id leaf_mem = MakeCompound(LeafFields(), sizeof(LeafRec), false);
  MKTREE_RETURN_IF_ERROR(ReadTable(tree.get(), "nodes", node_mem.get(), &nodes, path));
  MKTREE_RETURN_IF_ERROR(ReadTable(tree.get(), "split_nodes", split_mem.get(), &splits, path));
  MKTREE_RETURN_IF_ERROR(ReadTable(tree.get(), "leaves", leaf_mem.get(), &leaves, path));
  MKTREE_RETURN_IF_ERROR(ReadTable(tree.get(), "leaf_filter", H5T_NATIVE_UINT8, &c.tree.leaf_filter, path));
  if (Checksum(c.tree.leaf_filter) != sums[6]) return bad("leaf_filter checksum mismatch");
  c.tree.params = c.params;
  for (const NodeRec& r : nodes) c.tree.nodes.push_back(FromRec(r));
  for (const SplitRec& r : splits) {
    SplitNode s;
    s.cut = r.cut;
    s.child[0] = r.child[0];
    s.child[1] = r.child[1];
    s.axis = r.axis;
    s.label = static_cast<CellLabel>(r.label & 3);
    c.tree.split_nodes.push_back(s);
  }
  for (const LeafRec& r : leaves) c.tree.leaves.push_back(FromRec(r));
  if (Checksum(EncodeNodes(c.tree.nodes)) != sums[1]) return bad("nodes checksum mismatch");
  if (Checksum(EncodeSplitNodes(c.tree.split_nodes)) != sums[2]) return bad("split_nodes checksum mismatch");
  if (Checksum(EncodeLeaves(c.tree.leaves)) != sums[3]) return bad("leaves checksum mismatch");

  MKTREE_RETURN_IF_ERROR(ReadObjects(f, object_count, &c.objects, path));
  if (ObjectsChecksum(c.objects) != sums[4]) return bad("objects checksum mismatch");
  {
    H5Id d(H5Dopen2(f, "stats_json", H5P_DEFAULT), H5Dclose);
    if (!d.ok()) return bad("missing dataset stats_json");
    H5Id dt(H5Dget_type(d.get()), H5Tclose);
    H5Id space(H5Dget_space(d.get()), H5Sclose);
    if (H5Tget_class(dt.get()) != H5T_STRING || H5Tis_variable_str(dt.get()) != 0 ||
        H5Sget_simple_extent_type(space.get()) != H5S_SCALAR)
      return bad("stats_json is not a fixed-length string");
    const size_t n = H5Tget_size(dt.get());
    H5Id t = StringType(n);
    std::string js(n, '\0');
    if (H5Dread(d.get(), t.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, js.data()) < 0)
      return bad("reading stats_json: " + Hdf5ErrorText());
    js.resize(strnlen(js.data(), n));
    c.stats_json = std::move(js);
  }
  if (Checksum(c.stats_json) != sums[5]) return bad("stats_json checksum mismatch");

  // The pages dataset: shape, chunking and filters as we wrote them.
  H5Id dapl = PagesAccessList();
  H5Id pages(H5Dopen2(f, "pages", dapl.get()), H5Dclose);
  if (!pages.ok()) return bad("missing dataset pages");
  {
    H5Id space(H5Dget_space(pages.get()), H5Sclose);
    hsize_t dims[2] = {0, 0};
    if (H5Sget_simple_extent_ndims(space.get()) != 2 || H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0 ||
        dims[0] != page_count || dims[1] != mem_page)
      return bad("pages dataset has the wrong shape");
    H5Id dcpl(H5Dget_create_plist(pages.get()), H5Pclose);
    hsize_t chunk[2] = {0, 0};
    if (H5Pget_layout(dcpl.get()) != H5D_CHUNKED || H5Pget_chunk(dcpl.get(), 2, chunk) != 2 || chunk[0] != 1 ||
        chunk[1] != mem_page || H5Pget_nfilters(dcpl.get()) != 0)
      return bad("pages dataset is not chunked one page per chunk without filters");
    // Walk the chunk index once (metadata only, no page is read): damage to it is refused here rather
    // than at the first page read.
    hsize_t chunks = 0;
    if (H5Dget_num_chunks(pages.get(), space.get(), &chunks) < 0 || chunks != page_count)
      return bad("pages chunk index damaged (" + std::to_string(chunks) + " chunks for " + std::to_string(page_count) +
                 " pages)");
  }
  MKTREE_RETURN_IF_ERROR(ValidateStructure(c.tree, c.objects, page_count, path));
  if (opts.direct_io) out.notice = path + ": direct I/O is not supported by the HDF5 backend; using buffered reads";
  out.pages = std::make_unique<Hdf5PageStore>(path, std::move(file), std::move(pages), mem_page, page_count);
  return out;
}

}  // namespace mktree
