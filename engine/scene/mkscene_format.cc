#include "engine/scene/mkscene_format.h"

#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "storage/file_util.h"

namespace mktree {
namespace {

constexpr char kMagic[8] = {'M', 'K', 'S', 'C', 'E', 'N', 'E', '\0'};
// 1: float32 vertices (still read); 2: float64 vertices, so scenes keep their input's precision.
constexpr uint32_t kVersion = 2;
constexpr uint32_t kObjectTag = 0x424f4b4d;  // "MKOB" in file order
constexpr uint32_t kEndTag = 0x4e454b4d;     // "MKEN" in file order
constexpr size_t kHeaderBytes = 16;
constexpr size_t kEndBytes = 24;

std::string ErrnoText() { return std::strerror(errno); }

// Little-endian encoding on any host: a no-op swap on little-endian machines.
template <typename T>
T ToLittle(T v) {
  if constexpr (std::endian::native == std::endian::big) {
    uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&v, b, sizeof(T));
  }
  return v;
}

template <typename T>
void Append(std::vector<uint8_t>* out, T v) {
  v = ToLittle(v);
  const size_t at = out->size();
  out->resize(
      at + sizeof(T));  // resize + memcpy: vector::insert here trips a GCC 12 -Warray-bounds false positive
  std::memcpy(out->data() + at, &v, sizeof(T));
}

// Appends an array of fixed-width values; one memcpy on little-endian hosts.
template <typename T>
void AppendArray(std::vector<uint8_t>* out, const std::vector<T>& values) {
  const size_t at = out->size();
  out->resize(at + sizeof(T) * values.size());
  if constexpr (std::endian::native == std::endian::little) {
    if (!values.empty()) std::memcpy(out->data() + at, values.data(), sizeof(T) * values.size());
  } else {
    for (size_t i = 0; i < values.size(); ++i) {
      const T v = ToLittle(values[i]);
      std::memcpy(out->data() + at + sizeof(T) * i, &v, sizeof(T));
    }
  }
}

template <typename T>
T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return ToLittle(v);
}

template <typename T>
void LoadArray(const uint8_t* p, size_t count, std::vector<T>* out) {
  out->resize(count);
  if constexpr (std::endian::native == std::endian::little) {
    if (count) std::memcpy(out->data(), p, sizeof(T) * count);
  } else {
    for (size_t i = 0; i < count; ++i) (*out)[i] = Load<T>(p + sizeof(T) * i);
  }
}

// Positional reads of an .mks file through a window of it (1 MiB): walking small records reads each byte
// once, a large record is skipped or read straight into place. pread, not stdio: stdio read the file a
// block a call (glibc's setvbuf without a caller's buffer keeps the block size). Closes the file.
class WindowReader {
 public:
  static constexpr size_t kWindow = size_t{1} << 20;
  WindowReader(std::string path, std::FILE* f, uint64_t size) : path_(std::move(path)), f_(f), size_(size) {}
  WindowReader(const WindowReader&) = delete;
  WindowReader& operator=(const WindowReader&) = delete;
  ~WindowReader() { std::fclose(f_); }
  uint64_t size() const { return size_; }
  // n bytes at `offset`, valid until the next call (the window grows to n if it must).
  Result<const uint8_t*> At(uint64_t offset, size_t n) {
    if (offset < begin_ || offset + n > begin_ + buf_.size()) {
      if (offset > size_ || n > size_ - offset)
        return Status::Corruption(path_ + ": truncated at offset " + std::to_string(offset));
      MKTREE_RETURN_IF_ERROR(
          Fill(offset, std::max<uint64_t>(n, std::min<uint64_t>(kWindow, size_ - offset))));
    }
    return buf_.data() + (offset - begin_);
  }
  // Copies n bytes at `offset` to `dst`. REQUIRES offset + n <= size() (the caller says which record is
  // short). An end of file here means the file shrank after it was opened: an IOError.
  Status Read(uint64_t offset, size_t n, uint8_t* dst) {
    while (n > 0) {
      if (offset >= begin_ && offset - begin_ < buf_.size()) {
        const size_t k = static_cast<size_t>(std::min<uint64_t>(n, buf_.size() - (offset - begin_)));
        std::memcpy(dst, buf_.data() + (offset - begin_), k);
        dst += k;
        offset += k;
        n -= k;
        continue;
      }
      if (n >= kWindow) return storage_internal::PreadFull(::fileno(f_), dst, n, offset, path_);
      MKTREE_RETURN_IF_ERROR(Fill(offset, std::min<uint64_t>(kWindow, size_ - offset)));
    }
    return Status::Ok();
  }

 private:
  Status Fill(uint64_t offset, uint64_t bytes) {
    buf_.resize(static_cast<size_t>(bytes));
    begin_ = offset;
    Status st = storage_internal::PreadFull(::fileno(f_), buf_.data(), buf_.size(), offset, path_);
    if (!st.ok()) buf_.clear();
    return st;
  }

  const std::string path_;
  std::FILE* const f_;
  const uint64_t size_;
  uint64_t begin_ = 0;
  std::vector<uint8_t> buf_;
};

class MkSceneSource final : public SceneSource {
 public:
  MkSceneSource(std::string path, std::FILE* file, uint64_t file_size, ObjectId first_id, uint32_t version,
                uint64_t begin = kHeaderBytes, uint64_t first_index = 0, uint64_t limit = UINT64_MAX)
      : path_(std::move(path)),
        file_(path_, file, file_size),
        file_size_(file_size),
        first_id_(first_id),
        coordinate_bytes_(version == 1 ? 4 : 8),
        offset_(begin),
        first_index_(first_index),
        limit_(limit) {}
  Result<bool> Next(SceneObject* out) override {
    if (done_) return false;
    if (failed_) return Status::Internal(path_ + ": Next() after an error");
    Result<bool> r = ReadRecord(out);
    if (!r.ok()) failed_ = true;
    return r;
  }

 private:
  Status Corrupt(const std::string& what) const {
    return Status::Corruption(path_ + ": object " + std::to_string(first_index_ + objects_) + " (offset " +
                              std::to_string(offset_) + "): " + what);
  }

  // Reads `n` more bytes of the current record into record_.
  Status Read(size_t n) {
    const uint64_t have = offset_ + record_.size();
    if (n > file_size_ - have)
      return Corrupt("truncated (or a corrupt length): record needs " + std::to_string(n) +
                     " bytes at offset " + std::to_string(have) + ", file has " +
                     std::to_string(file_size_ - have) + " left");
    const size_t at = record_.size();
    record_.resize(at + n);
    return file_.Read(have, n, record_.data() + at);
  }

  Result<bool> ReadRecord(SceneObject* out) {
    record_.clear();
    if (objects_ == limit_) {  // a part (OpenMkScenePart): the end record was checked by ReadMkSceneLayout
      done_ = true;
      return false;
    }
    if (file_size_ == offset_) return Corrupt("truncated: end record missing");
    MKTREE_RETURN_IF_ERROR(Read(4));
    const uint32_t tag = Load<uint32_t>(record_.data());
    if (tag == kEndTag) {
      MKTREE_RETURN_IF_ERROR(Read(kEndBytes - 4));
      const uint64_t stored = Load<uint64_t>(record_.data() + 16);
      if (XXH3_64bits(record_.data(), 16) != stored) return Corrupt("end record checksum mismatch");
      const uint64_t count = Load<uint64_t>(record_.data() + 8);
      if (count != objects_)
        return Corrupt("end record says " + std::to_string(count) + " objects, file holds " +
                       std::to_string(objects_));
      if (offset_ + kEndBytes != file_size_)
        return Corrupt(std::to_string(file_size_ - offset_ - kEndBytes) +
                       " trailing bytes after the end record");
      done_ = true;
      return false;
    }
    if (tag != kObjectTag) return Corrupt("bad record tag");
    MKTREE_RETURN_IF_ERROR(Read(4));
    const uint32_t name_bytes = Load<uint32_t>(record_.data() + 4);
    MKTREE_RETURN_IF_ERROR(Read(uint64_t{name_bytes} + 8));
    const uint8_t* counts = record_.data() + 8 + name_bytes;
    const uint64_t nv = Load<uint32_t>(counts), nt = Load<uint32_t>(counts + 4);
    const uint64_t payload = 3 * coordinate_bytes_ * nv + 12 * nt + 8;
    if (payload > file_size_ - offset_ - record_.size())
      return Corrupt("truncated: " + std::to_string(nv) + " vertices and " + std::to_string(nt) +
                     " triangles need " + std::to_string(payload) + " bytes, file has " +
                     std::to_string(file_size_ - offset_ - record_.size()) + " left");
    MKTREE_RETURN_IF_ERROR(Read(payload));
    const size_t body = record_.size() - 8;
    if (XXH3_64bits(record_.data(), body) != Load<uint64_t>(record_.data() + body))
      return Corrupt("checksum mismatch");

    const uint8_t* p = record_.data() + 8;
    out->name.assign(reinterpret_cast<const char*>(p), name_bytes);
    if (out->source != path_) out->source = path_;
    out->attributes.clear();  // .mks keeps no attributes
    p += name_bytes + 8;
    if (coordinate_bytes_ == 4) {
      LoadArray(p, 3 * nv, &floats_);
      out->mesh.vertices.assign(floats_.begin(), floats_.end());
    } else {
      LoadArray(p, 3 * nv, &out->mesh.vertices);
    }
    LoadArray(p + 3 * coordinate_bytes_ * nv, 3 * nt, &out->mesh.triangles);
    for (double v : out->mesh.vertices) {
      if (!std::isfinite(v)) return Corrupt("non-finite vertex coordinate");
      if (std::fabs(v) > kMaxCoordinate) return Corrupt("vertex coordinate beyond 2^124 in magnitude");
    }
    for (uint32_t t : out->mesh.triangles)
      if (t >= nv) return Corrupt("triangle index " + std::to_string(t) + " out of range");
    out->id = static_cast<ObjectId>(first_id_ + objects_);
    offset_ += record_.size();
    ++objects_;
    return true;
  }

  const std::string path_;
  WindowReader file_;
  const uint64_t file_size_;
  const ObjectId first_id_;
  const uint64_t coordinate_bytes_;  // 4 (version 1) or 8
  uint64_t offset_;                  // file offset of the current record
  const uint64_t first_index_;       // the file's index of the first record read
  const uint64_t limit_;             // records to read (a part), or UINT64_MAX: to the end record
  uint64_t objects_ = 0;             // records read so far
  bool done_ = false;
  bool failed_ = false;
  std::vector<uint8_t> record_;
  std::vector<float> floats_;  // version 1 coordinates
};

}  // namespace

namespace {

struct OpenedScene {
  std::FILE* file = nullptr;
  uint64_t size = 0;
  uint32_t version = 0;
};

// Opens an .mks file and checks its header; the stream is left just after it.
Result<OpenedScene> OpenScene(const std::string& path) {
  auto fd = OpenSceneInput(path);
  if (!fd.ok()) return fd.status();
  std::FILE* f = ::fdopen(*fd, "rb");
  if (!f) {
    ::close(*fd);
    return Status::IOError(path + ": cannot open: " + ErrnoText());
  }
  struct stat st;
  if (::fstat(::fileno(f), &st) != 0) {
    std::fclose(f);
    return Status::IOError(path + ": cannot stat: " + ErrnoText());
  }
  uint8_t header[kHeaderBytes];
  const size_t got = std::fread(header, 1, kHeaderBytes, f);
  Status bad;
  if (got < kHeaderBytes) {
    bad = Status::Corruption(path + ": not an .mks scene: truncated header (" + std::to_string(got) +
                             " bytes)");
  } else if (std::memcmp(header, kMagic, sizeof(kMagic)) != 0) {
    bad = Status::Corruption(path + ": not an .mks scene: bad magic");
  } else if (const uint32_t version = Load<uint32_t>(header + 8); version != 1 && version != kVersion) {
    bad = Status::Unsupported(path + ": .mks version " + std::to_string(version) +
                              " (this build reads 1 and " + std::to_string(kVersion) + ")");
  }
  if (!bad.ok()) {
    std::fclose(f);
    return bad;
  }
  return OpenedScene{f, static_cast<uint64_t>(st.st_size), Load<uint32_t>(header + 8)};
}

// The size of the record at `p` from its header, or 0 when it is not an object record (wrong tag, or
// lengths that run past `limit`).
Result<uint64_t> RecordBytes(WindowReader& r, uint64_t p, uint64_t limit, uint64_t coordinate_bytes) {
  if (limit - p < 16 + 8) return uint64_t{0};
  MKTREE_ASSIGN_OR_RETURN(const uint8_t* h, r.At(p, 8));
  if (Load<uint32_t>(h) != kObjectTag) return uint64_t{0};
  const uint64_t name_bytes = Load<uint32_t>(h + 4);
  if (limit - p < 16 + 8 + name_bytes) return uint64_t{0};
  MKTREE_ASSIGN_OR_RETURN(const uint8_t* c, r.At(p + 8 + name_bytes, 8));
  const uint64_t bytes =
      24 + name_bytes + 3 * coordinate_bytes * Load<uint32_t>(c) + 12 * uint64_t{Load<uint32_t>(c + 4)};
  return bytes <= limit - p ? bytes : 0;
}

}  // namespace

Result<std::unique_ptr<SceneSource>> OpenMkSceneFile(const std::string& path, ObjectId first_id) {
  MKTREE_ASSIGN_OR_RETURN(OpenedScene o, OpenScene(path));
  return std::unique_ptr<SceneSource>(
      std::make_unique<MkSceneSource>(path, o.file, o.size, first_id, o.version));
}

Result<MkSceneLayout> ReadMkSceneLayout(const std::string& path) {
  MKTREE_ASSIGN_OR_RETURN(OpenedScene o, OpenScene(path));
  WindowReader r(path, o.file, o.size);
  MkSceneLayout l;
  l.file_size = o.size;
  l.version = o.version;
  l.body_begin = kHeaderBytes;
  if (o.size < kHeaderBytes + kEndBytes) return Status::Corruption(path + ": truncated: end record missing");
  l.body_end = o.size - kEndBytes;
  MKTREE_ASSIGN_OR_RETURN(const uint8_t* e, r.At(l.body_end, kEndBytes));
  auto bad = [&](const std::string& what) {
    return Status::Corruption(path + ": end record (offset " + std::to_string(l.body_end) + "): " + what);
  };
  if (Load<uint32_t>(e) != kEndTag) return bad("missing (bad tag): truncated or damaged");
  if (XXH3_64bits(e, 16) != Load<uint64_t>(e + 16)) return bad("checksum mismatch");
  l.objects = Load<uint64_t>(e + 8);
  return l;
}

Result<MkScenePart> FindMkScenePart(const std::string& path, const MkSceneLayout& layout,
                                    uint64_t range_begin, uint64_t range_end) {
  MKTREE_ASSIGN_OR_RETURN(OpenedScene o, OpenScene(path));
  WindowReader r(path, o.file, o.size);
  const uint64_t cb = layout.version == 1 ? 4 : 8, limit = layout.body_end;
  const uint64_t lo = std::max(range_begin, layout.body_begin), hi = std::min(range_end, limit);
  MkScenePart part;
  if (lo >= hi) return part;
  // The walk: record after record by their headers, to the first one at or past the range's end; 0 when
  // a header is not a record's.
  auto walk = [&](uint64_t p, uint64_t* objects) -> Result<uint64_t> {
    for (*objects = 0; p < hi; ++*objects) {
      MKTREE_ASSIGN_OR_RETURN(const uint64_t bytes, RecordBytes(r, p, limit, cb));
      if (bytes == 0) return uint64_t{0};
      p += bytes;
    }
    return p;
  };
  if (lo == layout.body_begin) {
    MKTREE_ASSIGN_OR_RETURN(part.end, walk(lo, &part.objects));
    if (part.end == 0)
      return Status::Corruption(path + ": the records from offset " + std::to_string(lo) +
                                " do not chain: a bad tag or lengths past the end record");
    part.found = true;
    part.begin = lo;
    return part;
  }
  // Resync: the first offset in [lo, hi) holding a tag whose record fits and checks out, and from which
  // the walk reaches the range's end (a forged record inside a name is followed by no record).
  for (uint64_t pos = lo; pos < hi;) {
    const size_t m = static_cast<size_t>(std::min<uint64_t>(WindowReader::kWindow, limit - pos));
    if (m < 4) break;
    MKTREE_ASSIGN_OR_RETURN(const uint8_t* d, r.At(pos, m));
    const void* q = ::memmem(d, m, "MKOB", 4);
    if (!q) {
      pos += m - 3;
      continue;
    }
    const uint64_t c = pos + static_cast<uint64_t>(static_cast<const uint8_t*>(q) - d);
    if (c >= hi) break;
    pos = c + 1;
    MKTREE_ASSIGN_OR_RETURN(const uint64_t bytes, RecordBytes(r, c, limit, cb));
    if (bytes == 0) continue;
    XXH3_state_t* state = XXH3_createState();
    XXH3_64bits_reset(state);
    Status st;
    for (uint64_t at = c; at < c + bytes - 8 && st.ok();) {
      const size_t n = static_cast<size_t>(std::min<uint64_t>(WindowReader::kWindow, c + bytes - 8 - at));
      auto chunk = r.At(at, n);
      if (!chunk.ok())
        st = chunk.status();
      else
        XXH3_64bits_update(state, *chunk, n);
      at += n;
    }
    const uint64_t sum = XXH3_64bits_digest(state);
    XXH3_freeState(state);
    MKTREE_RETURN_IF_ERROR(st);
    MKTREE_ASSIGN_OR_RETURN(const uint8_t* stored, r.At(c + bytes - 8, 8));
    if (sum != Load<uint64_t>(stored)) continue;
    MKTREE_ASSIGN_OR_RETURN(part.end, walk(c, &part.objects));
    if (part.end == 0) continue;
    part.found = true;
    part.begin = c;
    return part;
  }
  part.objects = 0;
  return part;
}

Status CheckMkSceneParts(const std::string& path, const MkSceneLayout& layout,
                         const std::vector<uint64_t>& range_begins, const std::vector<MkScenePart>& parts) {
  uint64_t expected = layout.body_begin, objects = 0;
  for (size_t i = 0; i < parts.size(); ++i) {
    const uint64_t hi =
        std::min(i + 1 < range_begins.size() ? range_begins[i + 1] : layout.body_end, layout.body_end);
    if (parts[i].found) {
      if (parts[i].begin != expected)
        return Status::Corruption(path + ": the records do not chain: one ends at offset " +
                                  std::to_string(expected) + ", a part was found to start at " +
                                  std::to_string(parts[i].begin));
      expected = parts[i].end;
      objects += parts[i].objects;
    } else if (expected < hi) {
      return Status::Corruption(path + ": no record found where one starts, at offset " +
                                std::to_string(expected));
    }
  }
  if (expected != layout.body_end || objects != layout.objects)
    return Status::Corruption(path + ": the records end at offset " + std::to_string(expected) + " with " +
                              std::to_string(objects) + " objects; the end record is at " +
                              std::to_string(layout.body_end) + " and says " +
                              std::to_string(layout.objects));
  return Status::Ok();
}

Result<std::unique_ptr<SceneSource>> OpenMkScenePart(const std::string& path, const MkSceneLayout& layout,
                                                     const MkScenePart& part, uint64_t first_index,
                                                     ObjectId first_id) {
  MKTREE_ASSIGN_OR_RETURN(OpenedScene o, OpenScene(path));
  const uint64_t begin = part.found ? part.begin : layout.body_begin;
  if (::fseeko(o.file, static_cast<off_t>(begin), SEEK_SET) != 0) {
    std::fclose(o.file);
    return Status::IOError(path + ": seek to " + std::to_string(begin) + ": " + ErrnoText());
  }
  return std::unique_ptr<SceneSource>(std::make_unique<MkSceneSource>(
      path, o.file, o.size, first_id, o.version, begin, first_index, part.found ? part.objects : 0));
}

MkSceneWriter::MkSceneWriter(std::string path, std::unique_ptr<AtomicFile> file)
    : path_(std::move(path)), file_(std::move(file)) {}

MkSceneWriter::~MkSceneWriter() = default;

Result<std::unique_ptr<MkSceneWriter>> MkSceneWriter::Create(const std::string& path) {
  auto file = AtomicFile::Create(path);
  if (!file.ok()) return file.status();
  auto writer = std::unique_ptr<MkSceneWriter>(new MkSceneWriter(path, std::move(*file)));
  std::vector<uint8_t> header(kMagic, kMagic + sizeof(kMagic));
  Append<uint32_t>(&header, kVersion);
  Append<uint32_t>(&header, 0);
  MKTREE_RETURN_IF_ERROR(writer->Put(header));
  return writer;
}

Status MkSceneWriter::Put(const std::vector<uint8_t>& bytes) {
  MKTREE_RETURN_IF_ERROR(file_->Write(bytes.data(), bytes.size()));
  bytes_ += bytes.size();
  return Status::Ok();
}

Status MkSceneWriter::Write(const SceneObject& object) {
  if (finished_) return Status::Internal(path_ + ": write after Finish()");
  const Mesh& mesh = object.mesh;
  const size_t nv = mesh.vertex_count(), nt = mesh.triangle_count();
  auto what = [&] { return path_ + ": object " + std::to_string(objects_) + " (" + object.name + "): "; };
  if (object.name.size() > UINT32_MAX || nv > UINT32_MAX || nt > UINT32_MAX ||
      mesh.vertices.size() != 3 * nv || mesh.triangles.size() != 3 * nt)
    return Status::InvalidArgument(what() + "too large or malformed for .mks");
  for (uint32_t t : mesh.triangles)
    if (t >= nv)
      return Status::InvalidArgument(what() + "triangle index " + std::to_string(t) + " out of range");
  record_.clear();
  Append<uint32_t>(&record_, kObjectTag);
  Append<uint32_t>(&record_, static_cast<uint32_t>(object.name.size()));
  record_.insert(record_.end(), object.name.begin(), object.name.end());
  Append<uint32_t>(&record_, static_cast<uint32_t>(nv));
  Append<uint32_t>(&record_, static_cast<uint32_t>(nt));
  AppendArray(&record_, mesh.vertices);
  AppendArray(&record_, mesh.triangles);
  Append<uint64_t>(&record_, XXH3_64bits(record_.data(), record_.size()));
  MKTREE_RETURN_IF_ERROR(Put(record_));
  ++objects_;
  return Status::Ok();
}

Status MkSceneWriter::Finish() {
  if (finished_) return Status::Internal(path_ + ": Finish() called twice");
  finished_ = true;
  record_.clear();
  Append<uint32_t>(&record_, kEndTag);
  Append<uint32_t>(&record_, 0);
  Append<uint64_t>(&record_, objects_);
  Append<uint64_t>(&record_, XXH3_64bits(record_.data(), record_.size()));
  MKTREE_RETURN_IF_ERROR(Put(record_));
  return file_->Commit();
}

}  // namespace mktree
