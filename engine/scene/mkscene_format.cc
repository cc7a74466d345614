#include "engine/scene/mkscene_format.h"

#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>

namespace mktree {
namespace {

constexpr char kMagic[8] = {'M', 'K', 'S', 'C', 'E', 'N', 'E', '\0'};
// 1: float32 vertices (still read); 2: float64 vertices, so scenes keep their input's precision.
constexpr uint32_t kVersion = 2;
constexpr uint32_t kObjectTag = 0x424f4b4d;  // "MKOB" in file order
constexpr uint32_t kEndTag = 0x4e454b4d;     // "MKEN" in file order
constexpr size_t kHeaderBytes = 16;
constexpr size_t kEndBytes = 24;
constexpr size_t kIoBufferBytes = 1 << 20;

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

class MkSceneSource final : public SceneSource {
 public:
  MkSceneSource(std::string path, std::FILE* file, uint64_t file_size, ObjectId first_id, uint32_t version)
      : path_(std::move(path)),
        file_(file),
        file_size_(file_size),
        first_id_(first_id),
        coordinate_bytes_(version == 1 ? 4 : 8),
        offset_(kHeaderBytes) {}
  ~MkSceneSource() override { std::fclose(file_); }

  Result<bool> Next(SceneObject* out) override {
    if (done_) return false;
    if (failed_) return Status::Internal(path_ + ": Next() after an error");
    Result<bool> r = ReadRecord(out);
    if (!r.ok()) failed_ = true;
    return r;
  }

 private:
  Status Corrupt(const std::string& what) const {
    return Status::Corruption(path_ + ": object " + std::to_string(objects_) + " (offset " +
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
    if (n && std::fread(record_.data() + at, 1, n, file_) != n) {
      if (std::ferror(file_))
        return Status::IOError(path_ + ": read failed at offset " + std::to_string(have));
      return Corrupt("truncated: unexpected end of file at offset " + std::to_string(have));
    }
    return Status::Ok();
  }

  Result<bool> ReadRecord(SceneObject* out) {
    record_.clear();
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
  std::FILE* const file_;
  const uint64_t file_size_;
  const ObjectId first_id_;
  const uint64_t coordinate_bytes_;  // 4 (version 1) or 8
  uint64_t offset_;                  // file offset of the current record
  uint64_t objects_ = 0;             // records read so far
  bool done_ = false;
  bool failed_ = false;
  std::vector<uint8_t> record_;
  std::vector<float> floats_;  // version 1 coordinates
};

}  // namespace

Result<std::unique_ptr<SceneSource>> OpenMkSceneFile(const std::string& path, ObjectId first_id) {
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
  std::setvbuf(f, nullptr, _IOFBF, kIoBufferBytes);
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
  return std::unique_ptr<SceneSource>(std::make_unique<MkSceneSource>(
      path, f, static_cast<uint64_t>(st.st_size), first_id, Load<uint32_t>(header + 8)));
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
