#include "engine/scene/ifc_reader.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>

extern char** environ;

namespace mktree {
namespace {

constexpr char kMagic[8] = {'M', 'K', 'I', 'F', 'C', 'S', '\0', '\0'};
constexpr uint32_t kVersion = 1;
constexpr char kProgramName[] = "mktree-ifc.mjs";
// Bounds on a record's parts: a stream from a broken program must not make us allocate without limit.
constexpr uint32_t kMaxText = 64u << 20;
constexpr uint32_t kMaxAttributes = 1u << 20;
constexpr uint32_t kMaxElements = 1u << 28;  // vertices or triangles of one object
constexpr size_t kMaxWarnings = 200;
constexpr size_t kMaxStderr = 4096;

// A little-endian value read on any host: a no-op on little-endian machines.
template <typename T>
T FromLittle(T v) {
  if constexpr (std::endian::native == std::endian::big) {
    uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    std::reverse(b, b + sizeof(T));
    std::memcpy(&v, b, sizeof(T));
  }
  return v;
}

std::string Env(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

bool IsFile(const std::string& p) {
  struct stat st;
  return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

bool IsDirectory(const std::string& p) {
  struct stat st;
  return ::stat(p.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

std::string Dirname(const std::string& p) {
  const size_t slash = p.rfind('/');
  return slash == std::string::npos ? "." : p.substr(0, slash);
}

// The status of an error record by what the program says went wrong.
Status ErrorRecordStatus(const std::string& path, const std::string& text) {
  std::string message = path + ": " + text;
  if (text.starts_with("unsupported")) return Status::Unsupported(std::move(message));
  if (text.starts_with("web-ifc is not installed") || text.starts_with("cannot read"))
    return Status::IOError(std::move(message));
  return Status::Corruption(std::move(message));
}

// The child: Node running the reader program, its stdout a pipe to us and its stderr an unlinked file.
class IfcProcess {
 public:
  IfcProcess() = default;
  IfcProcess(const IfcProcess&) = delete;
  IfcProcess& operator=(const IfcProcess&) = delete;
  ~IfcProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      Reap();
    }
    if (out_ >= 0) ::close(out_);
    if (err_ >= 0) ::close(err_);
  }

  Status Start(const std::string& node, const std::string& program, const std::string& path,
               const std::string& scratch_dir) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) return Status::IOError(path + ": pipe: " + std::strerror(errno));
    out_ = fds[0];
    err_ = ScratchFile(scratch_dir);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
    if (err_ >= 0) posix_spawn_file_actions_adddup2(&actions, err_, 2);
#if defined(__GLIBC__) && __GLIBC_PREREQ(2, 34)
    // Descriptors the build holds without O_CLOEXEC (its store, spill files, the writer lock) stay ours.
    posix_spawn_file_actions_addclosefrom_np(&actions, 3);
#endif
    std::vector<std::string> args = {node, program, path};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = node.find('/') == std::string::npos
                       ? ::posix_spawnp(&pid_, node.c_str(), &actions, nullptr, argv.data(), environ)
                       : ::posix_spawn(&pid_, node.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    if (rc != 0) {
      pid_ = -1;
      if (rc == ENOENT || rc == EACCES)
        return Status::IOError(path + ": reading IFC needs Node.js (20 or later) and '" + node +
                               "' cannot be run (" + std::strerror(rc) +
                               "): install the package nodejs (scripts/setup.sh), put node on PATH or set "
                               "MKTREE_NODE to it; or read IFC through assimp with MKTREE_IFC_READER=assimp");
      return Status::IOError(path + ": cannot start " + node + ": " + std::strerror(rc));
    }
    return Status::Ok();
  }

  int out() const { return out_; }

  // Waits for the child; "" when it exited with status 0, else how it ended and the tail of its stderr.
  std::string Finish() {
    const int status = Reap();
    std::string how;
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return "";
    if (WIFEXITED(status))
      how = "exit status " + std::to_string(WEXITSTATUS(status));
    else if (WIFSIGNALED(status))
      how = "killed by signal " + std::to_string(WTERMSIG(status));
    else
      how = "ended abnormally";
    const std::string err = StderrTail();
    return how + (err.empty() ? "" : ": " + err);
  }

  // The last lines of the child's stderr (at most kMaxStderr bytes), on one line.
  std::string StderrTail() const {
    if (err_ < 0) return "";
    struct stat st;
    if (::fstat(err_, &st) != 0 || st.st_size <= 0) return "";
    const off_t size = st.st_size;
    const off_t from = size > static_cast<off_t>(kMaxStderr) ? size - static_cast<off_t>(kMaxStderr) : 0;
    std::string text(static_cast<size_t>(size - from), '\0');
    const ssize_t got = ::pread(err_, text.data(), text.size(), from);
    text.resize(got > 0 ? static_cast<size_t>(got) : 0);
    std::replace(text.begin(), text.end(), '\n', ' ');
    while (!text.empty() && text.back() == ' ') text.pop_back();
    return text;
  }

 private:
  static int ScratchFile(std::string dir) {
    if (dir.empty()) dir = Env("TMPDIR");
    if (dir.empty()) dir = "/tmp";
    int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
    if (fd >= 0) return fd;
    std::string name = dir + "/mktree-ifc-stderr.XXXXXX";
    fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd >= 0) ::unlink(name.c_str());
    return fd;  // -1: the child's stderr is ours
  }

  int Reap() {
    int status = 0;
    while (pid_ > 0 && ::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    return status;
  }

  pid_t pid_ = -1;
  int out_ = -1;
  int err_ = -1;
};

// Buffered reads of the pipe.
class PipeReader {
 public:
  explicit PipeReader(int fd) : fd_(fd), buf_(1 << 20) {}
  // Reads n bytes; false at the end of the stream before them (an error in `*error` on a read failure).
  bool Read(void* dst, size_t n, std::string* error) {
    auto* out = static_cast<uint8_t*>(dst);
    while (n > 0) {
      if (at_ == end_ && !Fill(error)) return false;
      const size_t k = std::min(n, end_ - at_);
      std::memcpy(out, buf_.data() + at_, k);
      out += k;
      at_ += k;
      n -= k;
    }
    return true;
  }
  // Whether the stream has ended (nothing more to read).
  bool AtEnd(std::string* error) { return at_ == end_ && !Fill(error); }
  uint64_t offset() const { return consumed_ + at_; }

 private:
  bool Fill(std::string* error) {
    for (;;) {
      const ssize_t got = ::read(fd_, buf_.data(), buf_.size());
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) *error = std::strerror(errno);
      consumed_ += end_;
      at_ = end_ = 0;
      if (got <= 0) return false;
      end_ = static_cast<size_t>(got);
      return true;
    }
  }
  const int fd_;
  std::vector<uint8_t> buf_;
  size_t at_ = 0, end_ = 0;
  uint64_t consumed_ = 0;
};

class IfcSceneSource final : public SceneSource {
 public:
  IfcSceneSource(std::string path, std::string program, ObjectId first_id)
      : path_(std::move(path)), program_(std::move(program)), first_id_(first_id) {}

  ~IfcSceneSource() override {
    if (file_ >= 0) ::close(file_);
  }

  // Runs the program on the IFC file and reads its output.
  Status Start(const std::string& node, const std::string& scratch_dir) {
    MKTREE_RETURN_IF_ERROR(process_.Start(node, program_, path_, scratch_dir));
    reader_ = std::make_unique<PipeReader>(process_.out());
    return ReadHeader();
  }
  // Reads a saved stream from `fd` (taken).
  Status StartFile(int fd) {
    file_ = fd;
    reader_ = std::make_unique<PipeReader>(fd);
    return ReadHeader();
  }

  Result<bool> Next(SceneObject* out) override {
    if (done_) return false;
    if (failed_) return Status::Internal(path_ + ": Next() after an error");
    Result<bool> r = ReadRecords(out);
    if (!r.ok()) failed_ = true;
    return r;
  }

  std::vector<std::string> TakeWarnings() override {
    if (warnings_dropped_ > 0)
      warnings_.push_back(path_ + ": " + std::to_string(warnings_dropped_) + " more warnings not shown");
    warnings_dropped_ = 0;
    std::vector<std::string> out;
    out.swap(warnings_);
    return out;
  }

 private:
  static uint32_t Load32(const void* p) {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return FromLittle(v);
  }

  bool saved() const { return program_.empty(); }

  // A malformed stream: a damaged saved file, or a program that is not mktree's IFC reader.
  Status StreamError(const std::string& what) const {
    std::string message = path_ + ": MKIFCS stream: " + what;
    return saved() ? Status::Corruption(std::move(message)) : Status::Internal(std::move(message));
  }

  Status ReadHeader() {
    const std::string who = saved() ? "not an MKIFCS stream" : program_ + " wrote no MKIFCS stream";
    char header[16];
    if (!reader_->Read(header, sizeof(header), &read_error_)) return Died("before its stream header");
    if (std::memcmp(header, kMagic, sizeof(kMagic)) != 0)
      return saved() ? Status::Corruption(path_ + ": " + who + " (bad magic)")
                     : Status::Internal(path_ + ": " + who + " (is it mktree's IFC reader?)");
    if (Load32(header + 8) != kVersion)
      return Status::Unsupported(path_ + ": MKIFCS stream version " + std::to_string(Load32(header + 8)) +
                                 ", this build reads " + std::to_string(kVersion));
    return Status::Ok();
  }

  // The stream ended early: for a saved stream, truncation; for the program, why, from its exit status and
  // stderr.
  Status Died(const std::string& where) {
    if (saved())
      return Status::Corruption(path_ + ": truncated MKIFCS stream: it ends " + where +
                                (read_error_.empty() ? "" : " (" + read_error_ + ")"));
    const std::string how = process_.Finish();
    return Status::IOError(path_ + ": the IFC reader (" + program_ + ") stopped " + where +
                           (how.empty() ? "" : " (" + how + ")") +
                           (read_error_.empty() ? "" : "; reading its output: " + read_error_));
  }

  Result<uint32_t> U32(const char* what) {
    uint8_t b[4];
    if (!reader_->Read(b, 4, &read_error_)) return Died(std::string("in the middle of ") + what);
    return Load32(b);
  }

  Status Text(std::string* s, const char* what) {
    MKTREE_ASSIGN_OR_RETURN(const uint32_t n, U32(what));
    if (n > kMaxText) return StreamError(std::string(what) + " too long");
    s->resize(n);
    if (!reader_->Read(s->data(), n, &read_error_)) return Died(std::string("in the middle of ") + what);
    return Status::Ok();
  }

  template <typename T>
  Status Array(std::vector<T>* v, size_t n, const char* what) {
    v->resize(n);
    if (n && !reader_->Read(v->data(), n * sizeof(T), &read_error_))
      return Died(std::string("in the middle of ") + what);
    if constexpr (std::endian::native == std::endian::big)
      for (T& x : *v) x = FromLittle(x);
    return Status::Ok();
  }

  Result<bool> ReadRecords(SceneObject* out) {
    for (;;) {
      char tag[4];
      if (!reader_->Read(tag, 4, &read_error_)) return Died("before the end of its stream");
      const std::string_view t(tag, 4);
      if (t == "MKOB") {
        MKTREE_RETURN_IF_ERROR(ReadObject(out));
        return true;
      }
      std::string text;
      if (t == "MKWN") {
        MKTREE_RETURN_IF_ERROR(Text(&text, "a warning"));
        if (warnings_.size() < kMaxWarnings)
          warnings_.push_back(path_ + ": " + text);
        else
          ++warnings_dropped_;
        continue;
      }
      if (t == "MKER") {
        MKTREE_RETURN_IF_ERROR(Text(&text, "an error"));
        process_.Finish();
        return ErrorRecordStatus(path_, text);
      }
      if (t == "MKEN") return ReadEnd();
      return StreamError("bad record tag at offset " + std::to_string(reader_->offset() - 4));
    }
  }

  Result<bool> ReadEnd() {
    uint8_t b[12];
    if (!reader_->Read(b, sizeof(b), &read_error_)) return Died("in the middle of its end record");
    uint64_t count;
    std::memcpy(&count, b + 4, 8);
    count = FromLittle(count);
    if (!reader_->AtEnd(&read_error_)) return StreamError("bytes after its end");
    const std::string how = process_.Finish();
    if (!how.empty()) return Status::IOError(path_ + ": the IFC reader (" + program_ + ") failed: " + how);
    if (count != objects_)
      return StreamError("end record says " + std::to_string(count) + " objects, " +
                         std::to_string(objects_) + " were read");
    done_ = true;
    return false;
  }

  Status ReadObject(SceneObject* out) {
    MKTREE_RETURN_IF_ERROR(Text(&out->name, "an object's name"));
    MKTREE_ASSIGN_OR_RETURN(const uint32_t na, U32("an object's attributes"));
    if (na > kMaxAttributes) return StreamError("too many attributes");
    out->attributes.resize(na);
    for (ObjectAttribute& a : out->attributes) {
      MKTREE_RETURN_IF_ERROR(Text(&a.key, "an attribute"));
      MKTREE_RETURN_IF_ERROR(Text(&a.value, "an attribute"));
    }
    MKTREE_ASSIGN_OR_RETURN(const uint32_t nv, U32("an object's mesh"));
    MKTREE_ASSIGN_OR_RETURN(const uint32_t nt, U32("an object's mesh"));
    if (nv > kMaxElements || nt > kMaxElements)
      return StreamError("an object of " + std::to_string(nv) + " vertices and " + std::to_string(nt) +
                         " triangles");
    MKTREE_RETURN_IF_ERROR(Array(&out->mesh.vertices, 3 * size_t{nv}, "an object's vertices"));
    MKTREE_RETURN_IF_ERROR(Array(&out->mesh.triangles, 3 * size_t{nt}, "an object's triangles"));
    auto bad = [&](const std::string& what) {
      std::string who;
      for (const ObjectAttribute& a : out->attributes)
        if (a.key == "ifc_global_id" || a.key == "ifc_type") who += (who.empty() ? "" : " ") + a.value;
      return Status::Corruption(path_ + ": product " + std::to_string(objects_) + " (" + who + ", '" +
                                out->name + "'): " + what);
    };
    for (double v : out->mesh.vertices) {
      if (!std::isfinite(v)) return bad("non-finite vertex coordinate");
      if (std::fabs(v) > kMaxCoordinate) return bad("vertex coordinate beyond 2^124 in magnitude");
    }
    for (uint32_t i : out->mesh.triangles)
      if (i >= nv) return bad("triangle index " + std::to_string(i) + " out of range");
    if (out->source != path_) out->source = path_;
    out->id = static_cast<ObjectId>(first_id_ + objects_);
    ++objects_;
    return Status::Ok();
  }

  const std::string path_;
  const std::string program_;  // empty: a saved stream
  const ObjectId first_id_;
  IfcProcess process_;
  int file_ = -1;  // a saved stream's descriptor
  std::unique_ptr<PipeReader> reader_;
  std::string read_error_;
  uint64_t objects_ = 0;
  bool done_ = false;
  bool failed_ = false;
  std::vector<std::string> warnings_;
  size_t warnings_dropped_ = 0;
};

}  // namespace

bool IfcThroughAssimp() { return Env("MKTREE_IFC_READER") == "assimp"; }

std::string IfcReaderProgram() {
  std::string p = Env("MKTREE_IFC_READER");
  if (p.empty()) return std::string(MKTREE_IFC_TOOL_DIR) + "/" + kProgramName;
  if (IsDirectory(p)) return p + "/" + kProgramName;
  return p;
}

Result<std::unique_ptr<SceneSource>> OpenIfcFile(const std::string& path, ObjectId first_id,
                                                 const std::string& scratch_dir) {
  MKTREE_ASSIGN_OR_RETURN(const int fd, OpenSceneInput(path));  // missing, FIFO, directory: named here
  ::close(fd);
  const std::string program = IfcReaderProgram();
  if (!IsFile(program))
    return Status::IOError(path + ": the IFC reader program " + program +
                           " is missing: set MKTREE_IFC_READER to tools/ifc/mktree-ifc.mjs of an mktree "
                           "source tree (or to 'assimp')");
  const std::string web_ifc = Dirname(program) + "/node_modules/web-ifc/package.json";
  if (!IsFile(web_ifc))
    return Status::IOError(path + ": web-ifc is not installed for " + program +
                           ": run scripts/setup.sh (it runs npm ci --prefix " + Dirname(program) + ")");
  std::string node = Env("MKTREE_NODE");
  if (node.empty()) node = "node";
  auto source = std::make_unique<IfcSceneSource>(path, program, first_id);
  MKTREE_RETURN_IF_ERROR(source->Start(node, scratch_dir));
  return std::unique_ptr<SceneSource>(std::move(source));
}

Result<std::unique_ptr<SceneSource>> OpenIfcStreamFile(const std::string& path, ObjectId first_id) {
  MKTREE_ASSIGN_OR_RETURN(const int fd, OpenSceneInput(path));
  auto source = std::make_unique<IfcSceneSource>(path, "", first_id);
  MKTREE_RETURN_IF_ERROR(source->StartFile(fd));
  return std::unique_ptr<SceneSource>(std::move(source));
}

}  // namespace mktree
