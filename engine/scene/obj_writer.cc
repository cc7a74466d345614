#include "engine/scene/obj_writer.h"

#include <charconv>
#include <cstring>

namespace mktree {
namespace {

constexpr size_t kBufferBytes = 4 << 20;  // one write() per 4 MiB
constexpr size_t kMaxLine = 128;          // longest line we format without a bounds check

}  // namespace

ObjWriter::ObjWriter(std::string path, std::unique_ptr<AtomicFile> file)
    : path_(std::move(path)), file_(std::move(file)) {
  buffer_.reserve(kBufferBytes + 4096);
}

ObjWriter::~ObjWriter() = default;

Result<std::unique_ptr<ObjWriter>> ObjWriter::Create(const std::string& path) {
  auto file = AtomicFile::Create(path);
  if (!file.ok()) return file.status();
  auto writer = std::unique_ptr<ObjWriter>(new ObjWriter(path, std::move(*file)));
  static constexpr char kHeader[] =
      "# mktree scene (Wavefront OBJ): one `o` per object, relative face indices\n";
  writer->buffer_.insert(writer->buffer_.end(), kHeader, kHeader + sizeof(kHeader) - 1);
  return writer;
}

Status ObjWriter::Flush() {
  MKTREE_RETURN_IF_ERROR(file_->Write(buffer_.data(), buffer_.size()));
  bytes_ += buffer_.size();
  buffer_.clear();
  return Status::Ok();
}

Status ObjWriter::Write(const SceneObject& object) {
  if (finished_) return Status::Internal(path_ + ": write after Finish()");
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
  if (finished_) return Status::Internal(path_ + ": Finish() called twice");
  finished_ = true;
  MKTREE_RETURN_IF_ERROR(Flush());
  return file_->Commit();
}

}  // namespace mktree
