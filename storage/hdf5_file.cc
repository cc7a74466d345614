#include "storage/hdf5_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>

#include "storage/file_util.h"

// The writer's file driver below fills in H5FD_class_t, whose layout changed in HDF5 1.13.
#if H5_VERS_MAJOR != 1 || H5_VERS_MINOR > 12
#error "storage/hdf5_file.cc: WriterDriver() fills in the HDF5 1.10/1.12 H5FD_class_t; port it to this HDF5"
#endif

namespace mktree::hdf5 {

namespace {

std::recursive_mutex& Mutex() {
  static std::recursive_mutex mu;
  return mu;
}

// ---- The writer's file driver (WriterIo in hdf5_file.h says why) ----

struct WriterFapl {
  WriterIo* io;
};

struct DriverFile {
  H5FD_t pub;  // first: HDF5 hands the driver an H5FD_t* to it
  int fd = -1;
  haddr_t eoa = 0, eof = 0;
  dev_t dev = 0;
  ino_t ino = 0;
  WriterIo* io = nullptr;
  storage_internal::WritebackPacer writeback;
};

DriverFile* AsDriverFile(H5FD_t* f) { return reinterpret_cast<DriverFile*>(f); }
const DriverFile* AsDriverFile(const H5FD_t* f) { return reinterpret_cast<const DriverFile*>(f); }

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
  auto* f = new (std::nothrow) DriverFile;
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
  DriverFile* f = AsDriverFile(file);
  WriterIo* io = f->io;
  if (!io->discard && io->sync_on_close && io->ops->Fsync(f->fd) != 0) io->Record(errno, "fsync");
  if (::close(f->fd) != 0 && errno != EINTR && !io->discard) io->Record(errno, "close");
  delete f;
  return 0;
}

int WriterCmp(const H5FD_t* a, const H5FD_t* b) {
  const DriverFile* x = AsDriverFile(a);
  const DriverFile* y = AsDriverFile(b);
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

haddr_t WriterGetEoa(const H5FD_t* file, H5FD_mem_t /*type*/) { return AsDriverFile(file)->eoa; }
herr_t WriterSetEoa(H5FD_t* file, H5FD_mem_t /*type*/, haddr_t addr) {
  AsDriverFile(file)->eoa = addr;
  return 0;
}
haddr_t WriterGetEof(const H5FD_t* file, H5FD_mem_t /*type*/) { return AsDriverFile(file)->eof; }
herr_t WriterGetHandle(H5FD_t* file, hid_t /*fapl*/, void** handle) {
  *handle = &AsDriverFile(file)->fd;
  return 0;
}

bool OutOfRange(const DriverFile* f, haddr_t addr, size_t size) {
  return addr == HADDR_UNDEF || addr > f->eoa || size > f->eoa - addr;
}

herr_t WriterRead(H5FD_t* file, H5FD_mem_t /*type*/, hid_t /*dxpl*/, haddr_t addr, size_t size, void* buf) {
  DriverFile* f = AsDriverFile(file);
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
  DriverFile* f = AsDriverFile(file);
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
    f->writeback.Wrote(f->fd, done);
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
  DriverFile* f = AsDriverFile(file);
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
}  // namespace

Lock::Lock() : lock_(Mutex()) {
  thread_local bool quiet = false;
  if (!quiet) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    quiet = true;
  }
}

std::string ErrorText() {
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

hid_t ScalarType(FieldType t, bool file) {
  switch (t) {
    case FieldType::kU8:
      return file ? H5T_STD_U8LE : H5T_NATIVE_UINT8;
    case FieldType::kU16:
      return file ? H5T_STD_U16LE : H5T_NATIVE_UINT16;
    case FieldType::kU32:
      return file ? H5T_STD_U32LE : H5T_NATIVE_UINT32;
    case FieldType::kU64:
      return file ? H5T_STD_U64LE : H5T_NATIVE_UINT64;
    case FieldType::kI32:
      return file ? H5T_STD_I32LE : H5T_NATIVE_INT32;
    case FieldType::kF32:
      return file ? H5T_IEEE_F32LE : H5T_NATIVE_FLOAT;
    case FieldType::kF64:
      return file ? H5T_IEEE_F64LE : H5T_NATIVE_DOUBLE;
  }
  return -1;
}

void WriterIo::Record(int e, std::string what) {
  if (err == 0) {
    err = e;
    op = std::move(what);
  }
  discard = true;
}

Status WriterIo::ToStatus() const {
  return Status::IOError(path + ": " + op + ": " + storage_internal::ErrnoText(err));
}

Result<WriterFile> CreateWriterFile(const std::string& path, FileOps& ops) {
  WriterFile out;
  // Made before the file: the driver uses it until the file is closed.
  out.io = std::make_unique<WriterIo>(path, ops);
  const hid_t driver = WriterDriver();
  if (driver < 0) return Status::IOError(path + ": registering the HDF5 file driver: " + ErrorText());
  H5Id fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  const WriterFapl info{out.io.get()};
  if (H5Pset_driver(fapl.get(), driver, &info) < 0)
    return Status::IOError(path + ": setting the HDF5 file driver: " + ErrorText());
  H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V110, H5F_LIBVER_LATEST);
  out.file = H5Id(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), H5Fclose);
  if (!out.file.ok()) return Status::IOError(path + ": create: " + ErrorText());
  return out;
}

Status WriteAttr(hid_t loc, const char* name, FieldType type, const void* value, const std::string& path) {
  H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
  H5Id a(H5Acreate2(loc, name, ScalarType(type, true), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.ok() || H5Awrite(a.get(), ScalarType(type, false), value) < 0)
    return Status::IOError(path + ": writing attribute " + name + ": " + ErrorText());
  return Status::Ok();
}

namespace {

// Opens attribute `name`, which must hold one element (H5Aread writes as many elements as it holds).
Result<H5Id> OpenScalarAttr(hid_t loc, const char* name, const std::string& path) {
  if (H5Aexists(loc, name) <= 0) return Status::Corruption(path + ": missing attribute " + name);
  H5Id a(H5Aopen(loc, name, H5P_DEFAULT), H5Aclose);
  if (!a.ok()) return Status::Corruption(path + ": attribute " + name + ": " + ErrorText());
  H5Id space(H5Aget_space(a.get()), H5Sclose);
  if (!space.ok() || H5Sget_simple_extent_npoints(space.get()) != 1)
    return Status::Corruption(path + ": attribute " + name + " is not a single value");
  return a;
}

}  // namespace

Status ReadAttr(hid_t loc, const char* name, FieldType type, void* value, const std::string& path) {
  auto a = OpenScalarAttr(loc, name, path);
  if (!a.ok()) return a.status();
  H5Id t(H5Aget_type(a->get()), H5Tclose);
  const H5T_class_t cls = t.ok() ? H5Tget_class(t.get()) : H5T_NO_CLASS;
  if ((cls != H5T_INTEGER && cls != H5T_FLOAT) || H5Aread(a->get(), ScalarType(type, false), value) < 0)
    return Status::Corruption(path + ": reading attribute " + name + ": " + ErrorText());
  return Status::Ok();
}

Status WriteFieldAttr(hid_t loc, const RecordSchema& s, const char* field, const void* record,
                      const std::string& path) {
  const RecordField& f = s.field(field);
  return WriteAttr(loc, f.name, f.type, static_cast<const uint8_t*>(record) + f.offset, path);
}

Status ReadFieldAttr(hid_t loc, const RecordSchema& s, const char* field, void* record,
                     const std::string& path) {
  const RecordField& f = s.field(field);
  return ReadAttr(loc, f.name, f.type, static_cast<uint8_t*>(record) + f.offset, path);
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
    return Status::IOError(path + ": writing attribute " + name + ": " + ErrorText());
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
    return Status::Corruption(path + ": reading attribute " + name + ": " + ErrorText());
  s.resize(std::strlen(s.c_str()));
  return s;
}

}  // namespace mktree::hdf5
