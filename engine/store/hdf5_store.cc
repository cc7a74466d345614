// The HDF5 backend (layout in docs/store_format.md). One file:
//   /pages               uint8 [page_count x MemPage], chunked one page per chunk, no filters; pages are
//                        written and read whole with H5Dwrite_chunk/H5Dread_chunk, which bypass HDF5's
//                        chunk cache (also turned off on the dataset): the engine's PageCache is the only one
//   /tree/nodes, /tree/split_nodes, /tree/leaves   compound datasets with named fields
//   /objects/leaf, /objects/name_end, /objects/names   the object table's canonical encoding (tree_codec.h)
//   /stats_json          scalar fixed-length string
//   attributes on /      magic "MKTREE-HDF5" (written last), format_version, build parameters, codec, counts,
//                        and XXH3-64 checksums of the canonical encodings (tree_codec.h) of each part
// HDF5 is not thread-safe in Debian's serial build: every HDF5 call in this file runs under one
// process-wide mutex, so concurrent page reads from an HDF5 store are serialized.
#include <fcntl.h>
#include <hdf5.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>

#include "engine/store/store_backend.h"
#include "engine/tree/page_budget.h"
#include "storage/byte_io.h"
#include "storage/file_util.h"

// The writer's file driver below fills in H5FD_class_t, whose layout changed in HDF5 1.13.
#if H5_VERS_MAJOR != 1 || H5_VERS_MINOR > 12
#error \
    "engine/store/hdf5_store.cc: WriterDriver() fills in the HDF5 1.10/1.12 H5FD_class_t; port it to this HDF5"
#endif

namespace mktree {

namespace {

constexpr const char* kHdf5Magic = "MKTREE-HDF5";
// 2: the leaf filter holds 10-bit levels in 8 bytes an object; 3: the store frame (the origin attribute,
// boxes relative to it, vertices in each object's local frame), and the object table as its canonical
// encoding (leaf, name_end, names) instead of fixed-length names padded to the longest one.
constexpr uint32_t kHdf5FormatVersion = 3;
constexpr hsize_t kObjectChunkRows = 65536;
// Object names deflated more than this are stored unfiltered: at open, their length is bounded by this
// many times the bytes they take in the file.
constexpr uint64_t kMaxNamesInflation = 16;
// The longest string attribute a store holds (magic, codec); a longer one is damage.
constexpr size_t kMaxStringAttrBytes = 256;

std::recursive_mutex& Hdf5Mutex() {
  static std::recursive_mutex mu;
  return mu;
}

// Held around every HDF5 call. Also turns off HDF5's automatic error printing for the calling thread
// (per thread in thread-safe builds of HDF5), so that an HDF5 failure only ever reaches the user as
// our one-line Status, never as HDF5's own multi-line stack on stderr.
class Hdf5Lock {
 public:
  Hdf5Lock() : lock_(Hdf5Mutex()) {
    thread_local bool quiet = false;
    if (!quiet) {
      H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
      quiet = true;
    }
  }

 private:
  std::lock_guard<std::recursive_mutex> lock_;
};

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
  // The sec2 driver's I/O errors read "file read failed: time = <ctime, which ends in a newline>, filename =
  // ..., errno = 5, error message = 'Input/output error', buf = ..., offset = N": keep what failed, where
  // and why, on one line.
  const size_t em = msg.find("error message = '");
  if (em != std::string::npos && msg.find(": time = ") != std::string::npos) {
    const size_t b = em + 17, e = msg.find('\'', b);
    std::string out = msg.substr(0, msg.find(": time = "));
    const size_t off = msg.rfind("offset = ");
    if (off != std::string::npos) out += " at offset " + msg.substr(off + 9);
    msg = out + ": " + msg.substr(b, e == std::string::npos ? std::string::npos : e - b);
  }
  std::replace(msg.begin(), msg.end(), '\n', ' ');
  return msg.empty() ? "HDF5 error" : msg;
}

// ---- The writer's file driver ----
//
// POSIX pread/pwrite like HDF5's sec2 driver, except that a failed write, truncate, fsync or close is never
// reported to HDF5: the driver records the first error in WriterIo and stops writing (the file is going to
// be removed), and the writer checks WriterIo after each HDF5 call. Why: in HDF5 1.10 a flush that fails
// inside H5Fclose (or H5Dclose) frees the file's structures but leaves its identifier registered, so a
// second close, H5Fget_obj_count or the library's atexit cleanup (H5_term_library) touches freed memory:
// a full disk ended builds with signal 11. Here HDF5 never meets an I/O error while writing, so its close
// always completes and releases every identifier. Metadata written after the error is kept in memory,
// so that HDF5 reads back what it believes it wrote.
struct WriterIo {
  WriterIo(std::string p, FileOps& o) : path(std::move(p)), ops(&o) {}
  std::string path;
  FileOps* ops;                // the system calls (fault injection in tests)
  int err = 0;                 // first errno, 0 if none
  std::string op;              // what failed ("write at offset N")
  bool discard = false;        // after an error, or on Abort: no more file I/O
  bool sync_on_close = false;  // Finish: fsync before closing the descriptor
  std::vector<std::pair<haddr_t, std::vector<uint8_t>>> kept;  // metadata written while discarding

  void Record(int e, std::string what) {
    if (err == 0) {
      err = e;
      op = std::move(what);
    }
    discard = true;
  }
  bool failed() const { return err != 0; }
  Status ToStatus() const {
    return Status::IOError(path + ": " + op + ": " + storage_internal::ErrnoText(err));
  }
};

struct WriterFapl {
  WriterIo* io;
};

struct WriterFile {
  H5FD_t pub;  // first: HDF5 hands the driver an H5FD_t* to it
  int fd = -1;
  haddr_t eoa = 0, eof = 0;
  dev_t dev = 0;
  ino_t ino = 0;
  WriterIo* io = nullptr;
};

WriterFile* AsWriterFile(H5FD_t* f) { return reinterpret_cast<WriterFile*>(f); }
const WriterFile* AsWriterFile(const H5FD_t* f) { return reinterpret_cast<const WriterFile*>(f); }

void PushDriverError(hid_t minor, const std::string& msg) {
  H5Epush2(H5E_DEFAULT, __FILE__, "mktree writer driver", __LINE__, H5E_ERR_CLS, H5E_VFL, minor, "%s",
           msg.c_str());
}

H5FD_t* WriterOpen(const char* name, unsigned flags, hid_t fapl, haddr_t /*maxaddr*/) {
  const auto* info = static_cast<const WriterFapl*>(H5Pget_driver_info(fapl));
  if (info == nullptr || info->io == nullptr || name == nullptr) {
    PushDriverError(H5E_CANTOPENFILE, "no driver info");
    return nullptr;
  }
  int o = (flags & H5F_ACC_RDWR) ? O_RDWR : O_RDONLY;
  if (flags & H5F_ACC_TRUNC) o |= O_TRUNC;
  if (flags & H5F_ACC_CREAT) o |= O_CREAT;
  if (flags & H5F_ACC_EXCL) o |= O_EXCL;
  const int fd = ::open(name, o | O_CLOEXEC, 0644);
  if (fd < 0) {
    PushDriverError(H5E_CANTOPENFILE, storage_internal::ErrnoText(errno));
    return nullptr;
  }
  struct stat st;
  auto* f = new (std::nothrow) WriterFile;
  if (f == nullptr || ::fstat(fd, &st) != 0) {
    PushDriverError(H5E_CANTOPENFILE, f == nullptr ? "out of memory" : storage_internal::ErrnoText(errno));
    delete f;
    ::close(fd);
    return nullptr;
  }
  std::memset(&f->pub, 0, sizeof(f->pub));
  f->fd = fd;
  f->eof = static_cast<haddr_t>(st.st_size);
  f->dev = st.st_dev;
  f->ino = st.st_ino;
  f->io = info->io;
  return &f->pub;
}

herr_t WriterClose(H5FD_t* file) {
  WriterFile* f = AsWriterFile(file);
  WriterIo* io = f->io;
  if (!io->discard && io->sync_on_close && io->ops->Fsync(f->fd) != 0) io->Record(errno, "fsync");
  if (::close(f->fd) != 0 && errno != EINTR && !io->discard) io->Record(errno, "close");
  delete f;
  return 0;
}

int WriterCmp(const H5FD_t* a, const H5FD_t* b) {
  const WriterFile* x = AsWriterFile(a);
  const WriterFile* y = AsWriterFile(b);
  if (x->dev != y->dev) return x->dev < y->dev ? -1 : 1;
  if (x->ino != y->ino) return x->ino < y->ino ? -1 : 1;
  return 0;
}

herr_t WriterQuery(const H5FD_t* /*file*/, unsigned long* flags) {
  if (flags)
    *flags = H5FD_FEAT_AGGREGATE_METADATA | H5FD_FEAT_ACCUMULATE_METADATA | H5FD_FEAT_DATA_SIEVE |
             H5FD_FEAT_AGGREGATE_SMALLDATA;
  return 0;
}

haddr_t WriterGetEoa(const H5FD_t* file, H5FD_mem_t /*type*/) { return AsWriterFile(file)->eoa; }
herr_t WriterSetEoa(H5FD_t* file, H5FD_mem_t /*type*/, haddr_t addr) {
  AsWriterFile(file)->eoa = addr;
  return 0;
}
haddr_t WriterGetEof(const H5FD_t* file, H5FD_mem_t /*type*/) { return AsWriterFile(file)->eof; }
herr_t WriterGetHandle(H5FD_t* file, hid_t /*fapl*/, void** handle) {
  *handle = &AsWriterFile(file)->fd;
  return 0;
}

bool OutOfRange(const WriterFile* f, haddr_t addr, size_t size) {
  return addr == HADDR_UNDEF || addr > f->eoa || size > f->eoa - addr;
}

herr_t WriterRead(H5FD_t* file, H5FD_mem_t /*type*/, hid_t /*dxpl*/, haddr_t addr, size_t size, void* buf) {
  WriterFile* f = AsWriterFile(file);
  if (OutOfRange(f, addr, size)) {
    PushDriverError(H5E_OVERFLOW, "read past the end of the address space");
    return -1;
  }
  auto* p = static_cast<uint8_t*>(buf);
  size_t done = 0;
  while (done < size) {
    const ssize_t r = ::pread(f->fd, p + done, size - done, static_cast<off_t>(addr + done));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      PushDriverError(H5E_READERROR, "read at offset " + std::to_string(addr + done) + ": " +
                                         storage_internal::ErrnoText(errno));
      return -1;
    }
    if (r == 0) {  // past the end of the file: HDF5 expects zeros, as sec2 gives
      std::memset(p + done, 0, size - done);
      break;
    }
    done += static_cast<size_t>(r);
  }
  // Metadata written after an error lives here only, the newest last.
  for (const auto& [at, bytes] : f->io->kept) {
    const haddr_t lo = std::max<haddr_t>(at, addr), hi = std::min<haddr_t>(at + bytes.size(), addr + size);
    if (lo < hi) std::memcpy(p + (lo - addr), bytes.data() + (lo - at), hi - lo);
  }
  return 0;
}

herr_t WriterWrite(H5FD_t* file, H5FD_mem_t type, hid_t /*dxpl*/, haddr_t addr, size_t size,
                   const void* buf) {
  WriterFile* f = AsWriterFile(file);
  WriterIo* io = f->io;
  if (OutOfRange(f, addr, size)) {
    PushDriverError(H5E_OVERFLOW, "write past the end of the address space");
    return -1;
  }
  const auto* p = static_cast<const uint8_t*>(buf);
  if (!io->discard) {
    size_t done = 0;
    while (done < size) {
      const ssize_t r = io->ops->Pwrite(f->fd, p + done, size - done, addr + done);
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) {
        io->Record(errno, "write at offset " + std::to_string(addr + done));
        break;
      }
      done += static_cast<size_t>(r);
    }
  }
  // Metadata is kept: HDF5 reads it back and interprets it. Raw data (pages, tables) read back after an error
  // only feeds a file that is being thrown away.
  if (io->discard && type != H5FD_MEM_DRAW) io->kept.emplace_back(addr, std::vector<uint8_t>(p, p + size));
  f->eof = std::max<haddr_t>(f->eof, addr + size);
  return 0;
}

herr_t WriterFlush(H5FD_t* /*file*/, hid_t /*dxpl*/, hbool_t /*closing*/) { return 0; }

// The file's size becomes its end of address space, as sec2 does: a reader refuses a file shorter than that.
herr_t WriterTruncate(H5FD_t* file, hid_t /*dxpl*/, hbool_t /*closing*/) {
  WriterFile* f = AsWriterFile(file);
  if (f->eoa != f->eof) {
    if (!f->io->discard && f->io->ops->Ftruncate(f->fd, f->eoa) != 0)
      f->io->Record(errno, "truncate to " + std::to_string(f->eoa) + " bytes");
    f->eof = f->eoa;
  }
  return 0;
}

// The driver's id, registered on first use (again if the library was closed and reopened).
hid_t WriterDriver() {
  static hid_t id = -1;
  if (id >= 0 && H5Iis_valid(id) > 0) return id;
  static const H5FD_class_t cls = [] {
    H5FD_class_t c;
    std::memset(&c, 0, sizeof(c));
    c.name = "mktree_writer";
    c.maxaddr = static_cast<haddr_t>(INT64_MAX);  // off_t
    c.fc_degree = H5F_CLOSE_WEAK;
    c.fapl_size = sizeof(WriterFapl);
    c.open = WriterOpen;
    c.close = WriterClose;
    c.cmp = WriterCmp;
    c.query = WriterQuery;
    c.get_eoa = WriterGetEoa;
    c.set_eoa = WriterSetEoa;
    c.get_eof = WriterGetEof;
    c.get_handle = WriterGetHandle;
    c.read = WriterRead;
    c.write = WriterWrite;
    c.flush = WriterFlush;
    c.truncate = WriterTruncate;
    const H5FD_mem_t map[H5FD_MEM_NTYPES] = H5FD_FLMAP_DICHOTOMY;
    std::copy(std::begin(map), std::end(map), std::begin(c.fl_map));
    return c;
  }();
  id = H5FDregister(&cls);
  return id;
}

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
  hid_t mem;      // native type
  hid_t file;     // little-endian type
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

// Writes a 1-D contiguous dataset.
Status WriteTable(hid_t loc, const char* name, hid_t file_type, hid_t mem_type, const void* data, size_t n,
                  const std::string& path) {
  hsize_t dims[1] = {n};
  H5Id space(H5Screate_simple(1, dims, nullptr), H5Sclose);
  H5Id d(H5Dcreate2(loc, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
  if (!d.ok() || (n > 0 && H5Dwrite(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0))
    return Status::IOError(path + ": writing " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}

// The length of a 1-D dataset, refused (before anything is allocated for it) unless its elements of
// `file_bytes_each` bytes in the file fit in `max_bytes`: a damaged or crafted dataspace cannot make open
// allocate more than the file could hold.
Result<hsize_t> DatasetLength(hid_t d, const char* name, uint64_t max_bytes, const std::string& path) {
  H5Id space(H5Dget_space(d), H5Sclose);
  H5Id type(H5Dget_type(d), H5Tclose);
  hsize_t dims[1] = {0};
  if (!space.ok() || H5Sget_simple_extent_ndims(space.get()) != 1 ||
      H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0)
    return Status::Corruption(path + ": dataset " + name + " is not 1-D");
  const size_t each = type.ok() ? H5Tget_size(type.get()) : 0;
  if (each == 0) return Status::Corruption(path + ": dataset " + name + " has no valid type");
  if (dims[0] > max_bytes / each)
    return Status::Corruption(path + ": dataset " + name + " claims " + std::to_string(dims[0]) +
                              " elements of " + std::to_string(each) + " bytes, more than the file's " +
                              std::to_string(max_bytes) + " bytes hold");
  return dims[0];
}

// Reads a 1-D dataset into `out` (resized to its length, at most `max_bytes` in the file).
template <typename Rec>
Status ReadTable(hid_t loc, const char* name, hid_t mem_type, std::vector<Rec>* out, uint64_t max_bytes,
                 const std::string& path) {
  if (H5Lexists(loc, name, H5P_DEFAULT) <= 0) return Status::Corruption(path + ": missing dataset " + name);
  H5Id d(H5Dopen2(loc, name, H5P_DEFAULT), H5Dclose);
  if (!d.ok()) return Status::Corruption(path + ": dataset " + name + ": " + Hdf5ErrorText());
  auto n = DatasetLength(d.get(), name, max_bytes, path);
  if (!n.ok()) return n.status();
  out->resize(*n);
  if (*n > 0 && H5Dread(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out->data()) < 0)
    return Status::Corruption(path + ": reading " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}

template <typename T>
Status WriteAttr(hid_t loc, const char* name, hid_t file_type, hid_t mem_type, const T& v,
                 const std::string& path) {
  H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
  H5Id a(H5Acreate2(loc, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.ok() || H5Awrite(a.get(), mem_type, &v) < 0)
    return Status::IOError(path + ": writing attribute " + name + ": " + Hdf5ErrorText());
  return Status::Ok();
}
// Opens attribute `name`, which must hold one element (H5Aread writes as many elements as it holds).
Result<H5Id> OpenScalarAttr(hid_t loc, const char* name, const std::string& path) {
  if (H5Aexists(loc, name) <= 0) return Status::Corruption(path + ": missing attribute " + name);
  H5Id a(H5Aopen(loc, name, H5P_DEFAULT), H5Aclose);
  if (!a.ok()) return Status::Corruption(path + ": attribute " + name + ": " + Hdf5ErrorText());
  H5Id space(H5Aget_space(a.get()), H5Sclose);
  if (!space.ok() || H5Sget_simple_extent_npoints(space.get()) != 1)
    return Status::Corruption(path + ": attribute " + name + " is not a single value");
  return a;
}
template <typename T>
Status ReadAttr(hid_t loc, const char* name, hid_t mem_type, T* v, const std::string& path) {
  auto a = OpenScalarAttr(loc, name, path);
  if (!a.ok()) return a.status();
  H5Id t(H5Aget_type(a->get()), H5Tclose);
  const H5T_class_t cls = t.ok() ? H5Tget_class(t.get()) : H5T_NO_CLASS;
  if ((cls != H5T_INTEGER && cls != H5T_FLOAT) || H5Aread(a->get(), mem_type, v) < 0)
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
  auto a = OpenScalarAttr(loc, name, path);
  if (!a.ok()) return a.status();
  H5Id t(H5Aget_type(a->get()), H5Tclose);
  if (!t.ok() || H5Tget_class(t.get()) != H5T_STRING || H5Tis_variable_str(t.get()) > 0)
    return Status::Corruption(path + ": attribute " + name + " is not a fixed-length string");
  const size_t n = H5Tget_size(t.get());
  if (n == 0 || n > kMaxStringAttrBytes)
    return Status::Corruption(path + ": attribute " + name + " is " + std::to_string(n) + " bytes long");
  std::string s(n, '\0');
  if (H5Aread(a->get(), t.get(), s.data()) < 0)
    return Status::Corruption(path + ": reading attribute " + name + ": " + Hdf5ErrorText());
  s.resize(std::strlen(s.c_str()));
  return s;
}

// XXH3 of the header fields: parameters, codec, counts, version, origin.
uint64_t HeaderChecksum(const BuildParams& p, const CodecOptions& c, uint64_t pages, uint64_t objects,
                        const Vec3d& origin) {
  std::vector<uint8_t> b = EncodeParams(p, c);
  storage_internal::ByteWriter w(&b);
  w.Put<uint64_t>(pages);
  w.Put<uint64_t>(objects);
  w.Put<uint32_t>(kHdf5FormatVersion);
  for (int i = 0; i < 3; ++i) w.Put<double>(origin[i]);
  return Checksum(b);
}

// The store frame's origin: an attribute of three doubles.
Status WriteOrigin(hid_t loc, const Vec3d& origin, const std::string& path) {
  const hsize_t n = 3;
  const double v[3] = {origin.x, origin.y, origin.z};
  H5Id space(H5Screate_simple(1, &n, nullptr), H5Sclose);
  H5Id a(H5Acreate2(loc, "origin", H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.ok() || H5Awrite(a.get(), H5T_NATIVE_DOUBLE, v) < 0)
    return Status::IOError(path + ": writing attribute origin: " + Hdf5ErrorText());
  return Status::Ok();
}
Status ReadOrigin(hid_t loc, Vec3d* origin, const std::string& path) {
  if (H5Aexists(loc, "origin") <= 0) return Status::Corruption(path + ": missing attribute origin");
  H5Id a(H5Aopen(loc, "origin", H5P_DEFAULT), H5Aclose);
  H5Id space(H5Aget_space(a.get()), H5Sclose);
  hsize_t n = 0;
  if (!a.ok() || H5Sget_simple_extent_ndims(space.get()) != 1 ||
      H5Sget_simple_extent_dims(space.get(), &n, nullptr) < 0 || n != 3)
    return Status::Corruption(path + ": attribute origin is not three numbers");
  double v[3];
  if (H5Aread(a.get(), H5T_NATIVE_DOUBLE, v) < 0)
    return Status::Corruption(path + ": reading attribute origin: " + Hdf5ErrorText());
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(v[i])) return Status::Corruption(path + ": attribute origin is not finite");
    (*origin)[i] = v[i];
  }
  return Status::Ok();
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
  // `io` is the writer's driver state (null for a reader); it must outlive the file.
  Hdf5PageStore(std::string name, std::unique_ptr<WriterIo> io, H5Id file, H5Id pages, uint64_t mem_page,
                uint64_t count)
      : name_(std::move(name)),
        io_(std::move(io)),
        file_(std::move(file)),
        pages_(std::move(pages)),
        mem_page_(mem_page),
        count_(count),
        extent_(count) {}
  ~Hdf5PageStore() override { (void)Close(); }  // no caller to tell: Finish reports a writer's

  uint64_t page_bytes() const override { return mem_page_; }
  uint64_t page_count() const override { return count_; }
  const std::string& name() const override { return name_; }

  Status ReadPage(uint64_t index, uint8_t* out) const override {
    if (index >= count_) return PageOutOfRange(name_, index, count_);
    Hdf5Lock lock;
    const hsize_t offset[2] = {index, 0};
    hsize_t stored = 0;
    // Check the chunk's size first: H5Dread_chunk copies whatever size the file claims.
    if (H5Dget_chunk_storage_size(pages_.get(), offset, &stored) < 0 || stored != mem_page_) {
      H5Eclear2(H5E_DEFAULT);
      return Status::Corruption(name_ + ": page " + std::to_string(index) +
                                ": chunk missing or of the wrong size (" + std::to_string(stored) +
                                " bytes)");
    }
    uint32_t filters = 0;
    if (H5Dread_chunk(pages_.get(), H5P_DEFAULT, offset, &filters, out) < 0)
      return Status::IOError(name_ + ": page " + std::to_string(index) + ": " + Hdf5ErrorText());
    if (filters != 0)
      return Status::Corruption(name_ + ": page " + std::to_string(index) + ": unexpected filter mask");
    return Status::Ok();
  }

  Status WritePage(uint64_t index, const uint8_t* data) override {
    if (index > count_)
      return Status::InvalidArgument(name_ + ": page " + std::to_string(index) + " written out of order");
    Hdf5Lock lock;
    if (index >= extent_) {
      // Grow geometrically; chunks never written take no space, and Finish trims the extent.
      const hsize_t dims[2] = {std::max<hsize_t>(index + 1, 2 * extent_), mem_page_};
      if (H5Dset_extent(pages_.get(), dims) < 0) return Failed("extending pages");
      extent_ = dims[0];
    }
    const hsize_t offset[2] = {index, 0};
    if (H5Dwrite_chunk(pages_.get(), H5P_DEFAULT, 0, offset, mem_page_, data) < 0)
      return Failed("page " + std::to_string(index));
    MKTREE_RETURN_IF_ERROR(IoStatus());
    if (index == count_) ++count_;
    return Status::Ok();
  }

  Status Sync() override {
    Hdf5Lock lock;
    if (H5Fflush(file_.get(), H5F_SCOPE_LOCAL) < 0) return Failed("flush");
    return IoStatus();
  }

  // Trims the extent to the pages written (writer).
  Status Trim() {
    const hsize_t dims[2] = {count_, mem_page_};
    if (extent_ != count_ && H5Dset_extent(pages_.get(), dims) < 0) return Failed("trimming pages");
    extent_ = count_;
    return IoStatus();
  }
  hid_t file() const { return file_.get(); }

  // The writer's first I/O error, if any (the driver hides it from HDF5).
  Status IoStatus() const { return io_ && io_->failed() ? io_->ToStatus() : Status::Ok(); }
  // An HDF5 call failed while doing `what`: the I/O error behind it if there was one, else HDF5's message.
  Status Failed(const std::string& what) const {
    if (io_ && io_->failed()) {
      H5Eclear2(H5E_DEFAULT);
      return io_->ToStatus();
    }
    return Status::IOError(name_ + ": " + what + ": " + Hdf5ErrorText());
  }

  // Closes the file; with `sync`, fsyncs it first (the writer's Finish). Every HDF5 identifier of the file is
  // released, and the first I/O error of the whole write is reported.
  Status Close(bool sync = false) {
    Hdf5Lock lock;
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
  // Stops writing (the file is being thrown away) and closes it.
  void Abort() {
    Hdf5Lock lock;
    if (io_) io_->discard = true;
    (void)Close();  // the file is thrown away: its close cannot fail anything
  }

 private:
  std::string name_;
  std::unique_ptr<WriterIo> io_;
  H5Id file_, pages_;
  uint64_t mem_page_, count_;
  hsize_t extent_;
};

class Hdf5Writer : public StoreWriter::Impl {
 public:
  Hdf5Writer(std::string path, std::unique_ptr<Hdf5PageStore> store)
      : path_(std::move(path)), store_(std::move(store)) {}
  PageStore& pages() override { return *store_; }
  void Abort() override { store_->Abort(); }

  Status Finish(const StoreContents& c) override {
    {
      Hdf5Lock lock;
      Status st = WriteAll(c);
      // An I/O error is the cause of whatever HDF5 said after it.
      if (!store_->IoStatus().ok()) return store_->IoStatus();
      MKTREE_RETURN_IF_ERROR(st);
    }
    // HDF5 does not fsync: the driver does, before it closes the descriptor.
    return store_->Close(/*sync=*/true);
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
        MakeCompound(NodeFields(), sizeof(NodeRec), true),
        MakeCompound(NodeFields(), sizeof(NodeRec), false)));
    MKTREE_RETURN_IF_ERROR(write_table(
        "split_nodes", c.tree.split_nodes,
        [](const SplitNode& n) {
          return SplitRec{n.cut, {n.child[0], n.child[1]}, n.axis, static_cast<uint8_t>(n.label)};
        },
        SplitType(true), SplitType(false)));
    MKTREE_RETURN_IF_ERROR(write_table(
        "leaves", c.tree.leaves, [](const LeafInfo& l) { return ToRec(l); },
        MakeCompound(LeafFields(), sizeof(LeafRec), true),
        MakeCompound(LeafFields(), sizeof(LeafRec), false)));
    // The leaf filter: 8 uint8 per object (see docs/store_format.md), leaf by leaf.
    MKTREE_RETURN_IF_ERROR(WriteTable(tree.get(), "leaf_filter", H5T_STD_U8LE, H5T_NATIVE_UINT8,
                                      c.tree.leaf_filter.data(), c.tree.leaf_filter.size(), path_));
    MKTREE_RETURN_IF_ERROR(store_->IoStatus());

    MKTREE_RETURN_IF_ERROR(WriteObjects(f, c.objects));
    MKTREE_RETURN_IF_ERROR(store_->IoStatus());

    {  // stats JSON: a scalar fixed-length string dataset. Not variable-length: HDF5's global heap, where
       // those live, has no checksum, and a damaged heap entry crashes the library on read.
      const std::string& js = c.stats_json;
      H5Id t = StringType(std::max<size_t>(1, js.size()));
      H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
      H5Id d(H5Dcreate2(f, "stats_json", t.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
             H5Dclose);
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
    sums[0] = HeaderChecksum(c.params, c.codec, pages, objects, c.tree.origin);
    sums[1] = Checksum(EncodeNodes(c.tree.nodes));
    sums[2] = Checksum(EncodeSplitNodes(c.tree.split_nodes));
    sums[3] = Checksum(EncodeLeaves(c.tree.leaves));
    sums[4] = ObjectsChecksum(c.objects);
    sums[5] = Checksum(c.stats_json);
    sums[6] = Checksum(c.tree.leaf_filter);
    const char* sum_names[kChecksumCount] = {
        "checksum_header",  "checksum_nodes",      "checksum_split_nodes", "checksum_leaves",
        "checksum_objects", "checksum_stats_json", "checksum_leaf_filter"};
    MKTREE_RETURN_IF_ERROR(
        WriteAttr(f, "format_version", H5T_STD_U32LE, H5T_NATIVE_UINT32, kHdf5FormatVersion, path_));
    MKTREE_RETURN_IF_ERROR(
        WriteAttr(f, "block_size", H5T_STD_U32LE, H5T_NATIVE_UINT32, c.params.block_size, path_));
    MKTREE_RETURN_IF_ERROR(
        WriteAttr(f, "blocks_per_page", H5T_STD_U32LE, H5T_NATIVE_UINT32, c.params.blocks_per_page, path_));
    MKTREE_RETURN_IF_ERROR(
        WriteAttr(f, "balance_r", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, c.params.balance_r, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "split_tree_node_budget", H5T_STD_U32LE, H5T_NATIVE_UINT32,
                                     c.params.split_tree_node_budget, path_));
    MKTREE_RETURN_IF_ERROR(
        WriteStringAttr(f, "codec", c.codec.codec == Codec::kZstd ? "zstd" : "none", path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "zstd_level", H5T_STD_I32LE, H5T_NATIVE_INT32, level, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "shuffle", H5T_STD_U8LE, H5T_NATIVE_UINT8, shuffle, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "page_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, pages, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "object_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, objects, path_));
    MKTREE_RETURN_IF_ERROR(WriteOrigin(f, c.tree.origin, path_));
    for (int i = 0; i < kChecksumCount; ++i)
      MKTREE_RETURN_IF_ERROR(WriteAttr(f, sum_names[i], H5T_STD_U64LE, H5T_NATIVE_UINT64, sums[i], path_));
    // Last: the magic that makes the file a store.
    MKTREE_RETURN_IF_ERROR(WriteStringAttr(f, "magic", kHdf5Magic, path_));
    if (H5Fflush(f, H5F_SCOPE_LOCAL) < 0) return Status::IOError(path_ + ": flush: " + Hdf5ErrorText());
    return store_->IoStatus();
  }

  // /objects: the object table's canonical encoding (tree_codec.h), so that any name bytes round-trip and
  // the size follows the names' total length: leaf (uint32 per object), name_end (uint64 per object) and
  // names (all names concatenated, uint8), chunked with deflate (and shuffle for the integers). Names that
  // deflate more than kMaxNamesInflation times are stored unfiltered instead, so that at open the names'
  // length is bounded by the bytes the file spends on them (see ReadObjects).
  Status WriteObjects(hid_t f, const ObjectTable& t) {
    H5Id g(H5Gcreate2(f, "objects", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    if (!g.ok()) return Status::IOError(path_ + ": creating /objects: " + Hdf5ErrorText());
    auto write = [&](const char* name, hid_t file_type, hid_t mem_type, const void* data, hsize_t n,
                     bool shuffle) -> Result<H5Id> {
      if (n == 0 || H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0) {
        MKTREE_RETURN_IF_ERROR(WriteTable(g.get(), name, file_type, mem_type, data, n, path_));
        return H5Id();
      }
      const hsize_t dims[1] = {n}, chunk[1] = {std::min(n, kObjectChunkRows)};
      H5Id space(H5Screate_simple(1, dims, nullptr), H5Sclose);
      H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
      H5Pset_chunk(dcpl.get(), 1, chunk);
      if (shuffle) H5Pset_shuffle(dcpl.get());
      H5Pset_deflate(dcpl.get(), 4);
      H5Id d(H5Dcreate2(g.get(), name, file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
             H5Dclose);
      if (!d.ok() || H5Dwrite(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
        return Status::IOError(path_ + ": writing /objects/" + name + ": " + Hdf5ErrorText());
      return d;
    };
    MKTREE_RETURN_IF_ERROR(
        write("leaf", H5T_STD_U32LE, H5T_NATIVE_UINT32, t.leaf.data(), t.size(), true).status());
    MKTREE_RETURN_IF_ERROR(
        write("name_end", H5T_STD_U64LE, H5T_NATIVE_UINT64, t.name_end.data(), t.size(), true).status());
    auto names = write("names", H5T_STD_U8LE, H5T_NATIVE_UINT8, t.names.data(), t.names.size(), false);
    if (!names.ok()) return names.status();
    // (Flushed first: chunks still in HDF5's chunk cache take no storage yet.)
    if (names->ok() && H5Dflush(names->get()) < 0)
      return Status::IOError(path_ + ": writing /objects/names: " + Hdf5ErrorText());
    if (names->ok() && t.names.size() > kMaxNamesInflation * H5Dget_storage_size(names->get())) {
      names->reset();
      if (H5Ldelete(g.get(), "names", H5P_DEFAULT) < 0)
        return Status::IOError(path_ + ": rewriting /objects/names: " + Hdf5ErrorText());
      return WriteTable(g.get(), "names", H5T_STD_U8LE, H5T_NATIVE_UINT8, t.names.data(), t.names.size(),
                        path_);
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

// Reads /objects of a store of `expected` objects. Every length is checked before its allocation: leaf and
// name_end must have `expected` elements (bounded by the pages' size at open), names exactly the last name
// end, which must fit in the file (`file_bytes`).
Status ReadObjects(hid_t f, uint64_t expected, uint64_t file_bytes, ObjectTable* t, const std::string& path) {
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };
  if (H5Lexists(f, "objects", H5P_DEFAULT) <= 0) return bad("missing group objects");
  H5Id g(H5Gopen2(f, "objects", H5P_DEFAULT), H5Gclose);
  if (!g.ok()) return bad("objects: " + Hdf5ErrorText());
  auto open = [&](const char* name, uint64_t max_bytes, uint64_t want, H5Id* d) -> Status {
    if (H5Lexists(g.get(), name, H5P_DEFAULT) <= 0)
      return bad(std::string("missing dataset objects/") + name);
    *d = H5Id(H5Dopen2(g.get(), name, H5P_DEFAULT), H5Dclose);
    if (!d->ok()) return bad(std::string("objects/") + name + ": " + Hdf5ErrorText());
    const std::string full = std::string("objects/") + name;
    auto n = DatasetLength(d->get(), full.c_str(), max_bytes, path);
    if (!n.ok()) return n.status();
    if (*n != want)
      return bad(full + " has " + std::to_string(*n) + " elements, expected " + std::to_string(want));
    return Status::Ok();
  };
  H5Id leaf, name_end, names;
  // leaf and name_end may be compressed: their lengths are bounded by `expected`, not by the file.
  MKTREE_RETURN_IF_ERROR(open("leaf", UINT64_MAX, expected, &leaf));
  MKTREE_RETURN_IF_ERROR(open("name_end", UINT64_MAX, expected, &name_end));
  t->leaf.resize(expected);
  t->name_end.resize(expected);
  if (expected > 0 &&
      (H5Dread(leaf.get(), H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, t->leaf.data()) < 0 ||
       H5Dread(name_end.get(), H5T_NATIVE_UINT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, t->name_end.data()) < 0))
    return bad("reading objects: " + Hdf5ErrorText());
  uint64_t prev = 0;
  for (uint64_t i = 0; i < expected; ++i) {
    if (t->name_end[i] < prev) return bad("objects/name_end decreases at object " + std::to_string(i));
    prev = t->name_end[i];
  }
  // The names' length: at most the file's size if they are stored unfiltered, else kMaxNamesInflation
  // times the bytes their chunks take in the file.
  uint64_t names_bound = file_bytes;
  if (H5Lexists(g.get(), "names", H5P_DEFAULT) > 0) {
    H5Id d(H5Dopen2(g.get(), "names", H5P_DEFAULT), H5Dclose);
    H5Id dcpl(d.ok() ? H5Dget_create_plist(d.get()) : -1, H5Pclose);
    const int filters = dcpl.ok() ? H5Pget_nfilters(dcpl.get()) : -1;
    if (filters < 0) return bad("objects/names: " + Hdf5ErrorText());
    if (filters > 0)
      names_bound = kMaxNamesInflation * std::min<uint64_t>(H5Dget_storage_size(d.get()), file_bytes);
  }
  MKTREE_RETURN_IF_ERROR(open("names", names_bound, prev, &names));
  t->names.resize(prev);
  if (prev > 0 && H5Dread(names.get(), H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, t->names.data()) < 0)
    return bad("reading objects/names: " + Hdf5ErrorText());
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<StoreWriter::Impl>> CreateHdf5Writer(const std::string& temp_path,
                                                            const BuildParams& params, FileOps& ops) {
  Hdf5Lock lock;
  // Declared before the file: the driver uses it until the file is closed.
  auto io = std::make_unique<WriterIo>(temp_path, ops);
  const hid_t driver = WriterDriver();
  if (driver < 0)
    return Status::IOError(temp_path + ": registering the HDF5 file driver: " + Hdf5ErrorText());
  H5Id fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  const WriterFapl info{io.get()};
  if (H5Pset_driver(fapl.get(), driver, &info) < 0)
    return Status::IOError(temp_path + ": setting the HDF5 file driver: " + Hdf5ErrorText());
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
  H5Id pages(H5Dcreate2(file.get(), "pages", H5T_STD_U8LE, space.get(), H5P_DEFAULT, dcpl.get(), dapl.get()),
             H5Dclose);
  if (!pages.ok() || io->failed()) {
    pages.reset();
    file.reset();
    if (io->failed()) return io->ToStatus();
    return Status::IOError(temp_path + ": creating /pages: " + Hdf5ErrorText());
  }
  auto store = std::make_unique<Hdf5PageStore>(temp_path, std::move(io), std::move(file), std::move(pages),
                                               mem_page, 0);
  return std::unique_ptr<StoreWriter::Impl>(new Hdf5Writer(temp_path, std::move(store)));
}

Result<OpenedStore> OpenHdf5(const std::string& path, const ReadOptions& opts) {
  Hdf5Lock lock;
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };
  H5Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) return bad("HDF5 cannot open it (" + Hdf5ErrorText() + "): truncated or damaged");
  const hid_t f = file.get();
  hsize_t file_bytes = 0;
  if (H5Fget_filesize(f, &file_bytes) < 0) return bad("HDF5 cannot tell its size (" + Hdf5ErrorText() + ")");
  if (H5Aexists(f, "magic") <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return bad("an HDF5 file, but not an mktree store (no magic attribute)");
  }
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
  MKTREE_RETURN_IF_ERROR(
      ReadAttr(f, "split_tree_node_budget", H5T_NATIVE_UINT32, &c.params.split_tree_node_budget, path));
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
  const char* sum_names[kChecksumCount] = {"checksum_header",     "checksum_nodes",   "checksum_split_nodes",
                                           "checksum_leaves",     "checksum_objects", "checksum_stats_json",
                                           "checksum_leaf_filter"};
  uint64_t sums[kChecksumCount];
  for (int i = 0; i < kChecksumCount; ++i)
    MKTREE_RETURN_IF_ERROR(ReadAttr(f, sum_names[i], H5T_NATIVE_UINT64, &sums[i], path));
  MKTREE_RETURN_IF_ERROR(ReadOrigin(f, &c.tree.origin, path));
  if (HeaderChecksum(c.params, c.codec, page_count, object_count, c.tree.origin) != sums[0])
    return bad("header checksum mismatch");
  BuildParams check_params;
  CodecOptions check_codec;
  Status st = DecodeParams(EncodeParams(c.params, c.codec), &check_params, &check_codec);
  if (!st.ok()) return bad(st.message());
  const uint64_t mem_page = c.params.mem_page();
  // Counts bounded by the file before anything is sized by them (a checksum is no proof: it is not a MAC).
  // Every page is stored whole and unfiltered, and every object's leaf entry (at least its header) is in a
  // page.
  if (page_count > file_bytes / mem_page)
    return bad(std::to_string(page_count) + " pages of " + std::to_string(mem_page) +
               " bytes do not fit in its " + std::to_string(file_bytes) + " bytes");
  if (object_count > page_count * PagePayloadCapacity(mem_page) / kObjectEntryHeaderBytes)
    return bad(std::to_string(object_count) + " objects do not fit in its " + std::to_string(page_count) +
               " pages");

  // The tree: contiguous, unfiltered datasets, each at most the file's size.
  if (H5Lexists(f, "tree", H5P_DEFAULT) <= 0) return bad("missing group /tree");
  H5Id tree(H5Gopen2(f, "tree", H5P_DEFAULT), H5Gclose);
  if (!tree.ok()) return bad("/tree: " + Hdf5ErrorText());
  std::vector<NodeRec> nodes;
  std::vector<SplitRec> splits;
  std::vector<LeafRec> leaves;
  H5Id node_mem = MakeCompound(NodeFields(), sizeof(NodeRec), false);
  H5Id split_mem = SplitType(false);
  H5Id leaf_mem = MakeCompound(LeafFields(), sizeof(LeafRec), false);
  MKTREE_RETURN_IF_ERROR(ReadTable(tree.get(), "nodes", node_mem.get(), &nodes, file_bytes, path));
  MKTREE_RETURN_IF_ERROR(ReadTable(tree.get(), "split_nodes", split_mem.get(), &splits, file_bytes, path));
  MKTREE_RETURN_IF_ERROR(ReadTable(tree.get(), "leaves", leaf_mem.get(), &leaves, file_bytes, path));
  MKTREE_RETURN_IF_ERROR(
      ReadTable(tree.get(), "leaf_filter", H5T_NATIVE_UINT8, &c.tree.leaf_filter, file_bytes, path));
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

  MKTREE_RETURN_IF_ERROR(ReadObjects(f, object_count, file_bytes, &c.objects, path));
  if (ObjectsChecksum(c.objects) != sums[4]) return bad("objects checksum mismatch");
  {
    if (H5Lexists(f, "stats_json", H5P_DEFAULT) <= 0) return bad("missing dataset stats_json");
    H5Id d(H5Dopen2(f, "stats_json", H5P_DEFAULT), H5Dclose);
    if (!d.ok()) return bad("stats_json: " + Hdf5ErrorText());
    H5Id dt(H5Dget_type(d.get()), H5Tclose);
    H5Id space(H5Dget_space(d.get()), H5Sclose);
    if (H5Tget_class(dt.get()) != H5T_STRING || H5Tis_variable_str(dt.get()) != 0 ||
        H5Sget_simple_extent_type(space.get()) != H5S_SCALAR)
      return bad("stats_json is not a fixed-length string");
    const size_t n = H5Tget_size(dt.get());
    if (n == 0) return bad("stats_json has no valid type");
    if (n > file_bytes)
      return bad("stats_json claims " + std::to_string(n) + " bytes, more than the file's " +
                 std::to_string(file_bytes));
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
  if (H5Lexists(f, "pages", H5P_DEFAULT) <= 0) return bad("missing dataset pages");
  H5Id pages(H5Dopen2(f, "pages", dapl.get()), H5Dclose);
  if (!pages.ok()) return bad("pages: " + Hdf5ErrorText());
  {
    H5Id space(H5Dget_space(pages.get()), H5Sclose);
    hsize_t dims[2] = {0, 0};
    if (H5Sget_simple_extent_ndims(space.get()) != 2 ||
        H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0 || dims[0] != page_count ||
        dims[1] != mem_page)
      return bad("pages dataset has the wrong shape");
    H5Id dcpl(H5Dget_create_plist(pages.get()), H5Pclose);
    hsize_t chunk[2] = {0, 0};
    if (H5Pget_layout(dcpl.get()) != H5D_CHUNKED || H5Pget_chunk(dcpl.get(), 2, chunk) != 2 ||
        chunk[0] != 1 || chunk[1] != mem_page || H5Pget_nfilters(dcpl.get()) != 0)
      return bad("pages dataset is not chunked one page per chunk without filters");
    // Walk the chunk index once (metadata only, no page is read): damage to it is refused here rather
    // than at the first page read.
    hsize_t chunks = 0;
    if (H5Dget_num_chunks(pages.get(), space.get(), &chunks) < 0 || chunks != page_count)
      return bad("pages chunk index damaged (" + std::to_string(chunks) + " chunks for " +
                 std::to_string(page_count) + " pages)");
  }
  H5Eclear2(H5E_DEFAULT);
  MKTREE_RETURN_IF_ERROR(ValidateStructure(c.tree, c.objects, page_count, path));
  if (opts.direct_io)
    out.notice = path + ": direct I/O is not supported by the HDF5 backend; using buffered reads";
  out.pages =
      std::make_unique<Hdf5PageStore>(path, nullptr, std::move(file), std::move(pages), mem_page, page_count);
  return out;
}

}  // namespace mktree
