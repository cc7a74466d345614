#include "engine/generator/obj_writer.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>

namespace mktree {
namespace {

constexpr size_t kBufferBytes = 4 << 20;  // one write() per 4 MiB
constexpr size_t kMaxLine = 128;          // longest line we format without a bounds check

std::string ErrnoText() { return std::strerror(errno); }

}  // namespace

ObjWriter::ObjWriter(std::string path, std::string temp_path, int fd)
    : path_(std::move(path)), temp_path_(std::move(temp_path)), fd_(fd) {
  buffer_.reserve(kBufferBytes + 4096);
}

Result<std::unique_ptr<ObjWriter>> ObjWriter::Create(const std::string& path) {
  std::string temp = path + ".tmp-XXXXXX";
  const int fd = ::mkstemp(temp.data());
  if (fd < 0) return Status::IOError(path + ": cannot create file: " + ErrnoText());
  (void)::fchmod(fd, 0644);  // mkstemp makes it 0600; a scene is an ordinary file
  auto writer = std::unique_ptr<ObjWriter>(new ObjWriter(path, temp, fd));
  static constexpr char kHeader[] =
      "# mktree scene (Wavefront OBJ): one `o` per object, relative face indices\n";
  writer->buffer_.insert(writer->buffer_.end(), kHeader, kHeader + sizeof(kHeader) - 1);
  return writer;
}

ObjWriter::~ObjWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (!finished_) ::unlink(temp_path_.c_str());
}

Status ObjWriter::Flush() {
  const char* p = buffer_.data();
  size_t left = buffer_.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::IOError(path_ + ": write failed: " + ErrnoText());
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
  bytes_ += buffer_.size();
  buffer_.clear();
  return Status::Ok();
}

Status ObjWriter::Write(const SceneObject& object) {
  if (finished_ || fd_ < 0) return Status::Internal(path_ + ": write after Finish()");
  const Mesh& mesh = object.mesh;
  const size_t nv = mesh.vertex_count();
  if (object.name.find_first_of("\r\n") != std::string::npos)
    return Status::InvalidArgument(path_ + ": object " + std::to_string(object.id) +
                                   ": name has a line break");
  for (uint32_t t : mesh.triangles)
    if (t >= nv)
      return Status::InvalidArgument(path_ + ": object " + std::to_string(object.id) + " (" + object.name +
                                     "): triangle index " + std::to_string(t) + " out of range");

  // Grow once for this object, then format without bounds checks (every line is under kMaxLine).
  const size_t at = buffer_.size();
  buffer_.resize(at + object.name.size() + 4 + (nv + mesh.triangle_count()) * kMaxLine);
  char* p = buffer_.data() + at;
  *p++ = 'o';
  *p++ = ' ';
  std::memcpy(p, object.name.data(), object.name.size());
  p += object.name.size();
  *p++ = '\n';
  char* const limit = buffer_.data() + buffer_.size();
  for (size_t i = 0; i < mesh.vertices.size(); i += 3) {
    *p++ = 'v';
    for (int d = 0; d < 3; ++d) {
      *p++ = ' ';
      p = std::to_chars(p, limit, mesh.vertices[i + d]).ptr;
    }
    *p++ = '\n';
  }
  const long long count = static_cast<long long>(nv);
  for (size_t i = 0; i < mesh.triangles.size(); i += 3) {
    *p++ = 'f';
    for (int d = 0; d < 3; ++d) {
      *p++ = ' ';
      p = std::to_chars(p, limit, static_cast<long long>(mesh.triangles[i + d]) - count).ptr;
    }
    *p++ = '\n';
  }
  buffer_.resize(static_cast<size_t>(p - buffer_.data()));
  ++objects_;
  if (buffer_.size() >= kBufferBytes) return Flush();
  return Status::Ok();
}

Status ObjWriter::Finish() {
  if (finished_ || fd_ < 0) return Status::Internal(path_ + ": Finish() called twice");
  MKTREE_RETURN_IF_ERROR(Flush());
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) return Status::IOError(path_ + ": close failed: " + ErrnoText());
  if (::rename(temp_path_.c_str(), path_.c_str()) != 0)
    return Status::IOError(path_ + ": cannot rename " + temp_path_ + " onto it: " + ErrnoText());
  finished_ = true;
  return Status::Ok();
}

}  // namespace mktree
