#include "engine/scene/obj_reader.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <string_view>
#include <thread>
#include <vector>

#include "engine/scene/obj_chunk.h"
#include "storage/file_ops.h"
#include "storage/file_util.h"

namespace mktree {
namespace {

constexpr size_t kReadBufferBytes = size_t{1} << 20;

std::string Errno(const std::string& path) { return path + ": " + std::strerror(errno); }

// Open-addressing map from global vertex index to local (per-object) index. Its size follows the current
// object only, so memory stays bounded by the largest object.
class VertexIndexMap {
 public:
  // Returns the local index of `global`, inserting `next_local` when absent (then *inserted = true).
  uint32_t FindOrInsert(uint32_t global, uint32_t next_local, bool* inserted) {
    const uint32_t off = global - window_base_;
    if (off < kWindow) {
      if (window_.empty()) window_.assign(kWindow, 0);
      uint32_t& w = window_[off];
      *inserted = w == 0;
      if (w != 0) return w - 1;
      w = next_local + 1;
      window_used_.push_back(off);
      return next_local;
    }
    if ((size_ + 1) * 2 > slots_.size()) Grow();
    const uint32_t key = global + 1;  // 0 marks an empty slot
    size_t mask = slots_.size() - 1;
    size_t i = Hash(key) & mask;
    while (true) {
      Slot& s = slots_[i];
      if (s.key == key) {
        *inserted = false;
        return s.local;
      }
      if (s.key == 0) {
        s = Slot{key, next_local};
        used_.push_back(static_cast<uint32_t>(i));
        ++size_;
        *inserted = true;
        return next_local;
      }
      i = (i + 1) & mask;
    }
  }

  // Globals in [base, base + kWindow) go to a direct table rather than the hash table: the vertices an
  // object defines after its `o` line fall there. Only while the map is empty.
  void SetWindow(uint32_t base) { window_base_ = base; }

  void Clear() {
    for (uint32_t off : window_used_) window_[off] = 0;
    window_used_.clear();
    // Drop a table that a huge object left behind rather than clearing it for every small object.
    if (slots_.size() > 4096) {
      slots_.assign(4096, Slot{});
    } else {
      for (uint32_t i : used_) slots_[i] = Slot{};
    }
    used_.clear();
    size_ = 0;
  }

 private:
  struct Slot {
    uint32_t key = 0;
    uint32_t local = 0;
  };
  static size_t Hash(uint32_t k) { return (static_cast<uint64_t>(k) * 0x9E3779B97F4A7C15ull) >> 32; }

  void Grow() {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(old.empty() ? 1024 : old.size() * 2, Slot{});
    size_t mask = slots_.size() - 1;
    used_.clear();
    for (const Slot& s : old) {
      if (s.key == 0) continue;
      size_t i = Hash(s.key) & mask;
      while (slots_[i].key != 0) i = (i + 1) & mask;
      slots_[i] = s;
      used_.push_back(static_cast<uint32_t>(i));
    }
  }

  static constexpr uint32_t kWindow = 1 << 14;

  std::vector<Slot> slots_;
  std::vector<uint32_t> used_;  // the filled slots, so that clearing a small object costs its size
  size_t size_ = 0;
  uint32_t window_base_ = 0;
  std::vector<uint32_t> window_;  // local index + 1 of global window_base_ + i; 0 = absent
  std::vector<uint32_t> window_used_;
};

// The global vertex table: every vertex read so far, as OBJ faces may use any of them. Doubles, because
// coordinates far from 0 (UTM, geocentric) lose their detail in float32. Fixed-size blocks, of which the
// most recent (up to a budget of bytes) stay in RAM and older ones go to a spill file: memory stays bounded
// however many vertices the file has (24 bytes each), and faces, which nearly always use the vertices just
// before them, rarely read back. A block in RAM is reused for the next one once spilled, and mapped with its
// pages present when new (faulting them in 4 KiB at a time cost the applying thread more than filling
// them).
class VertexTable {
 public:
  // Keeps up to ram_bytes of blocks in RAM (one at least); the spill is written and read through `ops`.
  VertexTable(std::string path, size_t ram_bytes, std::string spill_dir, FileOps& ops)
      : path_(std::move(path)),
        spill_dir_(std::move(spill_dir)),
        ops_(ops),
        ram_(std::max<size_t>(ram_bytes / kBlockBytes, 1)) {}
  VertexTable(const VertexTable&) = delete;
  VertexTable& operator=(const VertexTable&) = delete;
  ~VertexTable() {
    for (double* b : ram_)
      if (b != nullptr) ::munmap(b, kBlockBytes);
    if (fd_ >= 0) ::close(fd_);
  }
  size_t size() const { return size_; }
  Status Push(const double xyz[3]) {
    if ((size_ & kBlockMask) == 0) MKTREE_RETURN_IF_ERROR(StartBlock(size_ >> kBlockShift));
    std::memcpy(&ram_[(size_ >> kBlockShift) % ram_.size()][3 * (size_ & kBlockMask)], xyz,
                3 * sizeof(double));
    ++size_;
    return Status::Ok();
  }
  // Vertex v's coordinates, valid until the next call; nullptr when a spilled one cannot be read (error()).
  // REQUIRES v < size().
  const double* At(uint32_t v) {
    const size_t block = v >> kBlockShift;
    if (block >= first_in_ram_) return &ram_[block % ram_.size()][3 * (v & kBlockMask)];
    // A spilled vertex: read back with its page of neighbours, which the next faces most likely use.
    const uint32_t page = v >> kReadBackShift;
    const size_t slot = page % kReadBackSlots;
    if (read_back_.empty()) {
      read_back_.resize(kReadBackSlots * kReadBackPage * 3);
      read_back_page_.assign(kReadBackSlots, kNoPage);
    }
    double* at = &read_back_[slot * kReadBackPage * 3];
    if (read_back_page_[slot] != page) {
      read_back_page_[slot] = kNoPage;
      if (Status st = storage_internal::PreadFull(fd_, at, kReadBackPage * 3 * sizeof(double),
                                                  uint64_t{page} * kReadBackPage * 3 * sizeof(double),
                                                  spill_name_, ops_);
          !st.ok()) {
        error_ = st;
        return nullptr;
      }
      read_back_page_[slot] = page;
    }
    return at + 3 * (v & (kReadBackPage - 1));
  }
  const Status& error() const { return error_; }

 private:
  static constexpr int kBlockShift = 16;
  static constexpr size_t kBlockVertices = size_t{1} << kBlockShift;
  static constexpr size_t kBlockMask = kBlockVertices - 1;
  static constexpr size_t kBlockBytes = 3 * sizeof(double) * kBlockVertices;
  // Spilled vertices are read back a page of 256 (6 KiB) at a time into 256 slots (1.5 MiB), a page
  // number's slot being fixed: faces that walk a spilled mesh in order cost one read per page.
  static constexpr int kReadBackShift = 8;
  static constexpr size_t kReadBackPage = size_t{1} << kReadBackShift;
  static constexpr size_t kReadBackSlots = 256;
  static constexpr uint32_t kNoPage = ~uint32_t{0};
  static_assert(kReadBackShift <= kBlockShift, "a read-back page lies in one block");

  // Makes room for block `block` (the next one), spilling the oldest block in RAM when all are in use.
  Status StartBlock(size_t block) {
    double*& slot = ram_[block % ram_.size()];
    if (block - first_in_ram_ == ram_.size()) {
      if (fd_ < 0) MKTREE_RETURN_IF_ERROR(OpenSpill());
      MKTREE_RETURN_IF_ERROR(storage_internal::PwriteFull(
          fd_, slot, kBlockBytes, uint64_t{first_in_ram_} * kBlockBytes, spill_name_, ops_));
      ++first_in_ram_;
      return Status::Ok();  // the spilled block's memory holds the new one
    }
    void* b = ::mmap(nullptr, kBlockBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_POPULATE,
                     -1, 0);
    if (b == MAP_FAILED) throw std::bad_alloc();
    slot = static_cast<double*>(b);
    return Status::Ok();
  }

  Status OpenSpill() {
    MKTREE_ASSIGN_OR_RETURN(storage_internal::UnnamedFile file,
                            storage_internal::OpenUnnamedFile(spill_dir_, ".mktree-vertices",
                                                              "the spill file for the vertices of " + path_));
    fd_ = file.fd;
    spill_name_ = file.where + " (the vertex spill of " + path_ + ")";
    return Status::Ok();
  }

  const std::string path_, spill_dir_;
  FileOps& ops_;
  std::vector<double*> ram_;  // block b, when b >= first_in_ram_, is ram_[b % ram_.size()]
  size_t first_in_ram_ = 0;   // blocks before it are in the spill file, at b * kBlockBytes
  size_t size_ = 0;
  int fd_ = -1;
  std::string spill_name_;
  std::vector<double> read_back_;         // kReadBackSlots pages of spilled vertices, allocated on first use
  std::vector<uint32_t> read_back_page_;  // the page each slot holds, or kNoPage
  Status error_;
};

template <typename T>
void CopyInto(const std::vector<T>& from, std::vector<T>* to) {
  if (to->capacity() > 2 * from.size() + 64) {
    std::vector<T>(from).swap(*to);
  } else {
    to->assign(from.begin(), from.end());
  }
}

enum class GroupRule { kUnknown, kGroupsStartObjects, kGroupsIgnored };

// The open file and its size when opened. Read with pread into each chunk's own buffer, not mapped: a file
// that shrinks under a mapping kills the process with SIGBUS, a short pread is an error to report.
struct InputFile {
  int fd = -1;
  size_t size = 0;
  ~InputFile() {
    if (fd >= 0) ::close(fd);
  }
};

// A chunk, its bytes and what reading them found.
struct LoadedChunk {
  uint64_t index = 0;
  ObjChunk chunk;
  std::vector<char> buffer;  // file bytes from buffer_offset on, the first `used`; reused (never shrinks)
  size_t buffer_offset = 0, used = 0;
  Status read_error;
};

class ObjReader final : public SceneSource {
 public:
  ObjReader(std::string path, std::unique_ptr<InputFile> file, ObjectId first_id,
            const ObjReadOptions& options);
  ~ObjReader() override;
  ObjReader(const ObjReader&) = delete;
  ObjReader& operator=(const ObjReader&) = delete;

  Result<bool> Next(SceneObject* out) override;

 private:
  // The next chunk in file order, read and parsed (nullptr after the last).
  LoadedChunk* TakeChunk();
  void ReleaseChunk();
  void Dispatch();  // fills the ring with chunks to parse (under mu_)
  void Work();      // a parsing thread
  // Reads chunk `c->index`: bytes [E(i * chunk_bytes_), E((i + 1) * chunk_bytes_)) of the file, where E(x)
  // is ObjLineBoundary from x (0 for x = 0, the file's size when none), then parses it.
  void LoadAndParse(LoadedChunk* c) const;
  // Makes c->buffer hold the file's bytes up to `to` (at most the size at open); false on a short read.
  bool Fill(LoadedChunk* c, size_t to) const;

  Status ErrorAt(uint64_t line, const std::string& what, bool unterminated = false) const;
  Status SpillErrorAt(uint64_t line, const Status& st) const;
  Status ChunkError(const ObjChunk& c) const;
  // Resolves refs[0, parts) into face_, adding new vertices to the mesh; EndFace adds the triangles.
  Status AddFace(const int64_t* refs, uint64_t parts, int stride, uint64_t line);
  void EndFace();
  Status AddVertices(const ObjChunk& c, const ObjOp& op);
  void SetGroups(std::string_view names);
  Result<bool> FileHasObjectLines();
  // Ends the current object (emitting it into *out when it has faces) and starts one named `name`.
  Result<bool> StartObject(std::string_view name, SceneObject* out);
  Result<bool> Emit(SceneObject* out);

  const std::string path_;
  const std::unique_ptr<InputFile> file_;
  const size_t chunk_bytes_;
  const uint64_t chunk_count_;
  uint64_t next_id_;

  // Chunks: ring_[seq % ring_.size()] holds chunk number seq; [consumed_, dispatched_) are in flight.
  std::mutex mu_;
  std::condition_variable work_cv_, done_cv_;
  std::vector<std::unique_ptr<LoadedChunk>> ring_;
  std::vector<char> ready_;         // per ring slot, under mu_
  std::deque<LoadedChunk*> queue_;  // dispatched, not yet taken by a parsing thread
  uint64_t dispatched_ = 0, consumed_ = 0;
  bool stop_ = false;
  std::vector<std::thread> threads_;

  // Applying the current chunk.
  LoadedChunk* loaded_ = nullptr;
  const ObjChunk* chunk_ = nullptr;
  size_t op_ = 0, vertex_at_ = 0, ref_at_ = 0, name_at_ = 0;
  uint64_t base_line_ = 0;  // lines before the current chunk
  uint64_t last_line_ = 0;  // line of the last operation applied

  VertexTable positions_;  // constructed with the options' RAM budget and spill folder
  uint64_t texcoord_count_ = 0, normal_count_ = 0;

  GroupRule group_rule_ = GroupRule::kUnknown;
  std::string name_;  // current object's name; empty = unnamed
  Mesh mesh_;
  VertexIndexMap local_of_global_;
  std::vector<uint32_t> face_;  // scratch: the current face's local indices

  // Attributes: the groups and material in force, and the current object's.
  std::vector<std::string> groups_;
  std::string material_;
  uint64_t attributes_version_ = 0, object_version_ = ~uint64_t{0};
  std::vector<ObjectAttribute> object_attributes_;

  Status error_;  // sticky: once failed, every later call fails the same way
  bool done_ = false;
};

ObjReader::ObjReader(std::string path, std::unique_ptr<InputFile> file, ObjectId first_id,
                     const ObjReadOptions& options)
    : path_(std::move(path)),
      file_(std::move(file)),
      chunk_bytes_(std::max<size_t>(options.chunk_bytes, 1)),
      chunk_count_((file_->size + chunk_bytes_ - 1) / chunk_bytes_),
      next_id_(first_id),
      positions_(path_, options.vertex_ram_bytes, options.spill_dir,
                 options.spill_file_ops ? *options.spill_file_ops : DefaultFileOps()) {
  int threads = options.threads;
  if (threads < 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = static_cast<int>(std::min<uint64_t>(threads, chunk_count_ > 1 ? chunk_count_ : 0));
  // Two chunks ahead of the parsers besides the one applied and one per parser: parsers that wait for a
  // free slot leave their core idle whenever the applying thread is the stage behind.
  ring_.resize(threads == 0 ? 1 : threads + 4);
  for (auto& c : ring_) c = std::make_unique<LoadedChunk>();
  ready_.assign(ring_.size(), 0);
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { Work(); });
  if (threads > 0) {
    std::lock_guard<std::mutex> lock(mu_);
    Dispatch();
  }
}

ObjReader::~ObjReader() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (auto& t : threads_) t.join();
}

bool ObjReader::Fill(LoadedChunk* c, size_t to) const {
  size_t have = c->buffer_offset + c->used;
  if (to <= have) return true;
  if (to - c->buffer_offset > c->buffer.size()) c->buffer.resize(to - c->buffer_offset);
  char* p = c->buffer.data() + c->used;
  while (have < to) {
    const ssize_t n = ::pread(file_->fd, p, to - have, static_cast<off_t>(have));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      c->read_error =
          Status::IOError("cannot read at byte " + std::to_string(have) + ": " + std::strerror(errno));
      return false;
    }
    if (n == 0) {
      c->read_error = Status::IOError("the file shrank while being read: it had " +
                                      std::to_string(file_->size) + " bytes when opened, it ends at byte " +
                                      std::to_string(have) + " now (truncated or rewritten?)");
      return false;
    }
    p += n;
    have += static_cast<size_t>(n);
    c->used += static_cast<size_t>(n);
  }
  return true;
}

void ObjReader::LoadAndParse(LoadedChunk* c) const {
  const size_t size = file_->size;
  const size_t from = static_cast<size_t>(std::min<uint64_t>(c->index * chunk_bytes_, size));
  const size_t to = static_cast<size_t>(std::min<uint64_t>((c->index + 1) * chunk_bytes_, size));
  c->read_error = Status::Ok();
  c->used = 0;
  c->buffer_offset = from >= 2 ? from - 2 : 0;  // ObjLineBoundary looks two bytes back
  c->chunk.Reset(from, from);
  // Boundaries past `to` need more bytes: grow the read by a lookahead that doubles.
  size_t lookahead = std::min<size_t>(chunk_bytes_, 4096);
  auto boundary = [&](size_t x, size_t* out) {
    if (x == 0 || x >= size) {
      *out = x == 0 ? 0 : size;
      return true;
    }
    while (true) {
      const size_t want = std::min(size, std::max(to, x) + lookahead);
      if (!Fill(c, want)) return false;
      const size_t b = ObjLineBoundary(c->buffer.data(), c->used, x - c->buffer_offset);
      if (b != SIZE_MAX) {
        *out = c->buffer_offset + b;
        return true;
      }
      if (want == size) {
        *out = size;
        return true;
      }
      lookahead *= 2;
    }
  };
  size_t begin = 0, end = 0;
  if (!boundary(from, &begin) || !boundary(to, &end)) return;
  if (!Fill(c, end)) return;
  c->chunk.Reset(begin, end);
  ParseObjChunk(c->buffer.data() + (begin - c->buffer_offset), &c->chunk);
}

void ObjReader::Dispatch() {
  while (dispatched_ - consumed_ < ring_.size() && dispatched_ < chunk_count_) {
    const size_t slot = dispatched_ % ring_.size();
    ring_[slot]->index = dispatched_;
    ready_[slot] = 0;
    ++dispatched_;
    if (!threads_.empty()) {
      queue_.push_back(ring_[slot].get());
      work_cv_.notify_one();
    }
  }
}

void ObjReader::Work() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    work_cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    LoadedChunk* c = queue_.front();
    queue_.pop_front();
    lock.unlock();
    LoadAndParse(c);
    lock.lock();
    for (size_t i = 0; i < ring_.size(); ++i) {
      if (ring_[i].get() == c) ready_[i] = 1;
    }
    done_cv_.notify_all();
  }
}

LoadedChunk* ObjReader::TakeChunk() {
  const size_t slot = consumed_ % ring_.size();
  if (threads_.empty()) {
    Dispatch();
    if (consumed_ == dispatched_) return nullptr;
    LoadAndParse(ring_[slot].get());
    return ring_[slot].get();
  }
  std::unique_lock<std::mutex> lock(mu_);
  if (consumed_ == dispatched_) return nullptr;
  done_cv_.wait(lock, [&] { return ready_[slot] != 0; });
  return ring_[slot].get();
}

void ObjReader::ReleaseChunk() {
  base_line_ += chunk_->lines;
  chunk_ = nullptr;
  loaded_ = nullptr;
  std::lock_guard<std::mutex> lock(mu_);
  ++consumed_;
  if (!threads_.empty()) Dispatch();
}

Status ObjReader::ErrorAt(uint64_t line, const std::string& what, bool unterminated) const {
  std::string msg = path_ + ":" + std::to_string(line) + ": " + what;
  if (unterminated) msg += " (the file ends inside this line: truncated?)";
  return Status::Corruption(std::move(msg));
}

// The vertex spill's failures (all of them I/O) are no fault of the OBJ file: not Corruption.
Status ObjReader::SpillErrorAt(uint64_t line, const Status& st) const {
  return Status::IOError(path_ + ":" + std::to_string(line) + ": " + st.message());
}

Status ObjReader::ChunkError(const ObjChunk& c) const {
  const uint64_t line = base_line_ + c.error_line;
  if (c.error_unsupported)
    return Status::Unsupported(path_ + ":" + std::to_string(line) + ": " + c.error_what);
  return ErrorAt(line, c.error_what, c.error_unterminated);
}

Status ObjReader::AddVertices(const ObjChunk& c, const ObjOp& op) {
  constexpr uint64_t kMaxVertices = std::numeric_limits<uint32_t>::max() - 1;
  if (positions_.size() + op.count > kMaxVertices) {
    // The first vertex past the limit, on line op.line + k of the run.
    const uint64_t k = kMaxVertices - positions_.size();
    return ErrorAt(base_line_ + op.line + k, "more than 2^32 - 2 vertices",
                   c.unterminated_line == op.line + k);
  }
  for (uint32_t i = 0; i < op.count; ++i) {
    if (Status st = positions_.Push(&c.vertices[vertex_at_ + 3 * size_t{i}]); !st.ok())
      return SpillErrorAt(base_line_ + op.line + i, st);
  }
  vertex_at_ += 3 * size_t{op.count};
  return Status::Ok();
}

Status ObjReader::AddFace(const int64_t* refs, uint64_t parts, int stride, uint64_t line) {
  static const char* const kWhat[3] = {"vertex", "texture coordinate", "normal"};
  const uint64_t counts[3] = {positions_.size(), texcoord_count_, normal_count_};
  face_.clear();
  for (uint64_t k = 0; k < parts; ++k) {
    const int64_t i = refs[k];
    if (i == 0) continue;  // an absent vt or vn
    const int part = stride == 1 ? 0 : static_cast<int>(k % 3);
    const int64_t resolved = i > 0 ? i - 1 : static_cast<int64_t>(counts[part]) + i;
    if (resolved < 0 || static_cast<uint64_t>(resolved) >= counts[part]) {
      return ErrorAt(base_line_ + line,
                     std::string("face: ") + kWhat[part] + " index " + std::to_string(i) + " out of range (" +
                         std::to_string(counts[part]) + " defined so far)",
                     chunk_->unterminated_line == line);
    }
    if (part != 0) continue;
    const uint32_t v = static_cast<uint32_t>(resolved);
    bool inserted = false;
    uint32_t local = local_of_global_.FindOrInsert(v, static_cast<uint32_t>(mesh_.vertex_count()), &inserted);
    if (inserted) {
      const double* p = positions_.At(v);
      if (p == nullptr) return SpillErrorAt(base_line_ + line, positions_.error());
      mesh_.vertices.push_back(p[0]);
      mesh_.vertices.push_back(p[1]);
      mesh_.vertices.push_back(p[2]);
    }
    face_.push_back(local);
  }
  return Status::Ok();
}

void ObjReader::EndFace() {
  for (size_t i = 1; i + 1 < face_.size(); ++i) {
    mesh_.triangles.push_back(face_[0]);
    mesh_.triangles.push_back(face_[i]);
    mesh_.triangles.push_back(face_[i + 1]);
  }
  if (object_version_ != attributes_version_) {
    object_version_ = attributes_version_;
    auto add = [this](const char* key, const std::string& value) {
      for (const ObjectAttribute& a : object_attributes_) {
        if (a.key == key && a.value == value) return;
      }
      object_attributes_.push_back(ObjectAttribute{key, value});
    };
    for (const std::string& g : groups_) add("group", g);
    if (!material_.empty()) add("material", material_);
  }
}

void ObjReader::SetGroups(std::string_view names) {
  groups_.clear();
  for (std::string_view n = ObjNextToken(&names); !n.empty(); n = ObjNextToken(&names))
    groups_.emplace_back(n);
  ++attributes_version_;
}

// True when some line of the file starts with the `o` directive. Reads the file through its own
// descriptor so that the mapping's pages are not all brought in; stops at the first hit.
Result<bool> ObjReader::FileHasObjectLines() {
  int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Status::IOError(Errno(path_));
  std::unique_ptr<char[]> buf(new char[kReadBufferBytes]);
  enum { kLineStart, kSawO, kInLine } state = kLineStart;
  bool found = false;
  while (!found) {
    ssize_t n = ::read(fd, buf.get(), kReadBufferBytes);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      Status st = Status::IOError(Errno(path_));
      ::close(fd);
      return st;
    }
    if (n == 0) {
      found = state == kSawO;
      break;
    }
    const char* p = buf.get();
    const char* end = p + n;
    while (p < end && !found) {
      char c = *p;
      if (state == kInLine) {
        const void* nl = std::memchr(p, '\n', end - p);
        if (nl == nullptr) break;
        p = static_cast<const char*>(nl) + 1;
        state = kLineStart;
        continue;
      }
      if (state == kLineStart) {
        state = c == 'o' ? kSawO : (c == ' ' || c == '\t' ? kLineStart : (c == '\n' ? kLineStart : kInLine));
      } else {  // kSawO: "o" must be the whole directive
        found = c == ' ' || c == '\t' || c == '\r' || c == '\n';
        state = c == '\n' ? kLineStart : kInLine;
      }
      ++p;
    }
  }
  ::close(fd);
  return found;
}

Result<bool> ObjReader::Emit(SceneObject* out) {
  if (next_id_ > std::numeric_limits<ObjectId>::max()) {
    return ErrorAt(last_line_, "more than 2^32 objects");
  }
  out->id = static_cast<ObjectId>(next_id_++);
  out->name = name_.empty() ? "object_" + std::to_string(out->id) : name_;
  out->source = path_;
  out->attributes.swap(object_attributes_);
  object_attributes_.clear();
  object_version_ = ~uint64_t{0};
  // A small mesh is copied into *out's buffers (ingest reuses its slots) rather than moved: mesh_ keeps
  // its capacity, so the next object does not regrow it allocation by allocation. A slot buffer much
  // larger than the object is replaced, so that slots hold no more than a moved buffer would. A large
  // mesh is moved, not copied and not kept.
  constexpr size_t kCopyBytes = size_t{1} << 20;
  if (8 * mesh_.vertices.capacity() + 4 * mesh_.triangles.capacity() > kCopyBytes) {
    out->mesh = std::move(mesh_);
    mesh_ = Mesh();
  } else {
    CopyInto(mesh_.vertices, &out->mesh.vertices);
    CopyInto(mesh_.triangles, &out->mesh.triangles);
    mesh_.vertices.clear();
    mesh_.triangles.clear();
  }
  local_of_global_.Clear();
  return true;
}

Result<bool> ObjReader::StartObject(std::string_view name, SceneObject* out) {
  // Vertices enter an object's mesh only through its faces, so a faceless object left nothing behind.
  bool emitted = false;
  if (mesh_.triangle_count() > 0) {
    auto r = Emit(out);
    if (!r.ok()) return r;
    emitted = true;
  }
  name_.assign(name);
  local_of_global_.SetWindow(static_cast<uint32_t>(positions_.size()));
  return emitted;
}

Result<bool> ObjReader::Next(SceneObject* out) {
  if (!error_.ok()) return error_;
  if (done_) return false;
  auto fail = [this](Status st) -> Result<bool> {
    error_ = std::move(st);
    return error_;
  };
  while (true) {
    if (chunk_ == nullptr) {
      loaded_ = TakeChunk();
      op_ = 0;
      vertex_at_ = ref_at_ = name_at_ = 0;
      if (loaded_ != nullptr) {
        // Every line before this chunk was applied; its own bytes could not all be read.
        if (!loaded_->read_error.ok()) {
          return fail(Status::IOError(path_ + ":" + std::to_string(base_line_ + 1) + ": " +
                                      loaded_->read_error.message()));
        }
        chunk_ = &loaded_->chunk;
      }
      if (chunk_ == nullptr) {
        done_ = true;
        if (mesh_.triangle_count() == 0) return false;
        auto r = Emit(out);
        if (!r.ok()) return fail(r.status());
        return true;
      }
    }
    const ObjChunk& c = *chunk_;
    while (op_ < c.ops.size()) {
      const ObjOp& op = c.ops[op_++];
      last_line_ = base_line_ + op.line;
      Status st;
      switch (op.kind) {
        case ObjOpKind::kVertices:
          st = AddVertices(c, op);
          break;
        case ObjOpKind::kTexcoords:
          texcoord_count_ += op.count;
          break;
        case ObjOpKind::kNormals:
          normal_count_ += op.count;
          break;
        case ObjOpKind::kFaces: {
          const uint64_t parts = uint64_t{op.stride} * op.corners;
          for (uint32_t f = 0; f < op.count && st.ok(); ++f) {
            st = AddFace(&c.refs[ref_at_], parts, op.stride, op.line + f);
            ref_at_ += parts;
            if (st.ok()) EndFace();
          }
          break;
        }
        case ObjOpKind::kFaceError:
          st = AddFace(c.refs.data() + ref_at_, c.error_stop, op.stride, op.line);
          if (st.ok()) st = ChunkError(c);
          break;
        case ObjOpKind::kMaterial:
          material_.assign(c.names, name_at_, op.count);
          name_at_ += op.count;
          ++attributes_version_;
          break;
        case ObjOpKind::kObject:
        case ObjOpKind::kGroup: {
          const std::string_view name(c.names.data() + name_at_, op.count);
          name_at_ += op.count;
          if (op.kind == ObjOpKind::kObject) {
            group_rule_ = GroupRule::kGroupsIgnored;
          } else {
            SetGroups(name);
            if (group_rule_ == GroupRule::kUnknown) {
              auto has_o = FileHasObjectLines();
              if (!has_o.ok()) return fail(has_o.status());
              group_rule_ = *has_o ? GroupRule::kGroupsIgnored : GroupRule::kGroupsStartObjects;
            }
          }
          if (op.kind == ObjOpKind::kObject || group_rule_ == GroupRule::kGroupsStartObjects) {
            auto r = StartObject(name, out);
            if (!r.ok()) return fail(r.status());
            if (*r) return true;
          }
          break;
        }
        case ObjOpKind::kError:
          st = ChunkError(c);
          break;
      }
      if (!st.ok()) return fail(std::move(st));
    }
    ReleaseChunk();
  }
}

}  // namespace

Result<std::unique_ptr<SceneSource>> OpenObjFile(const std::string& path, ObjectId first_id) {
  return OpenObjFile(path, first_id, ObjReadOptions());
}

Result<std::unique_ptr<SceneSource>> OpenObjFile(const std::string& path, ObjectId first_id,
                                                 const ObjReadOptions& options) {
  auto fd = OpenSceneInput(path);
  if (!fd.ok()) return fd.status();
  struct stat st;
  if (::fstat(*fd, &st) != 0) {
    Status s = Status::IOError(Errno(path));
    ::close(*fd);
    return s;
  }
  auto file = std::make_unique<InputFile>();
  file->fd = *fd;
  file->size = static_cast<size_t>(st.st_size);
  ::posix_fadvise(file->fd, 0, 0, POSIX_FADV_SEQUENTIAL);
  return std::unique_ptr<SceneSource>(new ObjReader(path, std::move(file), first_id, options));
}

}  // namespace mktree
