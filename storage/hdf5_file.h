// HDF5 basics for the stores' HDF5 backend: the process-wide lock every HDF5 call runs under, owned
// identifiers, HDF5's error stack as one line, a file driver for writing that survives I/O errors, and
// scalar and string attributes with their sizes checked before they are read.
//
// Thread safety: Debian's HDF5 is the serial build, which is not thread-safe: hold a Lock around every
// HDF5 call (the functions here expect the caller to hold it). It also turns off HDF5's automatic error
// printing for the calling thread, so that an HDF5 failure reaches the user only as our one-line Status.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "mktree/status.h"
#include "storage/file_ops.h"
#include "storage/record_schema.h"

namespace mktree::hdf5 {

// Held around every HDF5 call (recursive: functions that lock call each other).
class Lock {
 public:
  Lock();

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

// The innermost message of HDF5's current error stack (e.g. "truncated file: eof = ..."), on one line;
// clears the stack.
std::string ErrorText();

// The HDF5 type of a field type: little-endian as stored in a file, or native in memory.
hid_t ScalarType(FieldType t, bool file);

// ---- Writing through the writer's file driver ----
//
// POSIX pread/pwrite like HDF5's sec2 driver, except that a failed write, truncate, fsync or close is never
// reported to HDF5: the driver records the first error in WriterIo and stops writing (the file is going to
// be removed), and the writer checks WriterIo after each HDF5 call. Why: in HDF5 1.10 a flush that fails
// inside H5Fclose (or H5Dclose) frees the file's structures but leaves its identifier registered, so a
// second close, H5Fget_obj_count or the library's atexit cleanup (H5_term_library) touches freed memory:
// a full disk ended builds with signal 11. Here HDF5 never meets an I/O error while writing, so its close
// always completes and releases every identifier. Metadata written after the error is kept in memory,
// so that HDF5 reads back what it believes it wrote. The files are plain HDF5: readers use HDF5's default
// driver.
struct WriterIo {
  WriterIo(std::string p, FileOps& o) : path(std::move(p)), ops(&o) {}
  std::string path;
  FileOps* ops;                // the system calls (fault injection in tests)
  int err = 0;                 // first errno, 0 if none
  std::string op;              // what failed ("write at offset N")
  bool discard = false;        // after an error, or on Abort: no more file I/O
  bool sync_on_close = false;  // fsync before closing the descriptor
  std::vector<std::pair<haddr_t, std::vector<uint8_t>>> kept;  // metadata written while discarding

  void Record(int e, std::string what);
  bool failed() const { return err != 0; }
  Status ToStatus() const;
};

// A file created through the writer driver. `io` is the driver's state: it outlives `file` (members are
// destroyed in reverse order).
struct WriterFile {
  std::unique_ptr<WriterIo> io;
  H5Id file;
};
// Creates (truncates) `path` in the HDF5 1.10 format (checksummed object headers and chunk indexes),
// writing through `ops`.
Result<WriterFile> CreateWriterFile(const std::string& path, FileOps& ops);

// ---- Attributes ----
// Errors are IOError (writing) or Corruption (reading), naming `path` and the attribute.

Status WriteAttr(hid_t loc, const char* name, FieldType type, const void* value, const std::string& path);
template <typename T>
Status WriteAttr(hid_t loc, const char* name, const T& value, const std::string& path) {
  return WriteAttr(loc, name, FieldTypeOf<T>(), &value, path);
}
// Reads a scalar attribute of integer or float type (converted to `type`); it must hold one value.
Status ReadAttr(hid_t loc, const char* name, FieldType type, void* value, const std::string& path);
template <typename T>
Status ReadAttr(hid_t loc, const char* name, T* value, const std::string& path) {
  return ReadAttr(loc, name, FieldTypeOf<T>(), value, path);
}
// Field `field` of `record` (a record of schema `s`) as the attribute of the field's name and type.
Status WriteFieldAttr(hid_t loc, const RecordSchema& s, const char* field, const void* record,
                      const std::string& path);
Status ReadFieldAttr(hid_t loc, const RecordSchema& s, const char* field, void* record,
                     const std::string& path);

// The longest string attribute ReadStringAttr accepts; a longer one is damage.
inline constexpr size_t kMaxStringAttrBytes = 256;
// A fixed-length, NUL-padded string type of `size` bytes. Not variable-length: those live in HDF5's
// global heap, which has no checksum, and a damaged heap entry crashes the library on read.
H5Id StringType(size_t size);
Status WriteStringAttr(hid_t loc, const char* name, const std::string& s, const std::string& path);
Result<std::string> ReadStringAttr(hid_t loc, const char* name, const std::string& path);

}  // namespace mktree::hdf5
