#include "engine/ingest/exchange_record.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

namespace mktree {

namespace {

void PutU32(std::vector<uint8_t>* b, uint32_t v) {
  const size_t n = b->size();
  b->resize(n + 4);
  std::memcpy(b->data() + n, &v, 4);
}
void PutBytes(std::vector<uint8_t>* b, const void* p, size_t n) {
  const auto* c = static_cast<const uint8_t*>(p);
  b->insert(b->end(), c, c + n);
}
void PutStr(std::vector<uint8_t>* b, const std::string& s) {
  PutU32(b, static_cast<uint32_t>(s.size()));
  PutBytes(b, s.data(), s.size());
}

class SpillSource final : public SceneSource {
 public:
  SpillSource(std::string path, std::FILE* f) : path_(std::move(path)), f_(f) {}
  ~SpillSource() override { std::fclose(f_); }
  SpillSource(const SpillSource&) = delete;
  SpillSource& operator=(const SpillSource&) = delete;

  Result<bool> Next(SceneObject* o) override {
    uint32_t n = 0;
    const size_t got = std::fread(&n, 1, 4, f_);
    if (got == 0 && std::feof(f_)) return false;
    buf_.resize(n);
    if (got != 4 || std::fread(buf_.data(), 1, n, f_) != n) return Status::IOError(path_ + ": truncated");
    at_ = 0;
    o->id = U32();
    o->name = Str();
    o->source = Str();
    o->attributes.resize(U32());
    for (ObjectAttribute& a : o->attributes) {
      a.key = Str();
      a.value = Str();
    }
    o->mesh.vertices.resize(3 * size_t{U32()});
    Bytes(o->mesh.vertices.data(), 8 * o->mesh.vertices.size());
    o->mesh.triangles.resize(3 * size_t{U32()});
    Bytes(o->mesh.triangles.data(), 4 * o->mesh.triangles.size());
    if (!ok_ || at_ != buf_.size()) return Status::Internal(path_ + ": a damaged exchange record");
    return true;
  }

 private:
  void Bytes(void* p, size_t n) {
    if (at_ + n > buf_.size()) {
      ok_ = false;
      return;
    }
    std::memcpy(p, buf_.data() + at_, n);
    at_ += n;
  }
  uint32_t U32() {
    uint32_t v = 0;
    Bytes(&v, 4);
    return v;
  }
  std::string Str() {
    std::string s(ok_ ? std::min<size_t>(U32(), buf_.size()) : 0, '\0');
    Bytes(s.data(), s.size());
    return s;
  }

  std::string path_;
  std::FILE* f_;
  std::vector<uint8_t> buf_;
  size_t at_ = 0;
  bool ok_ = true;
};

}  // namespace

void EncodeExchangeRecord(const SceneObject& o, std::vector<uint8_t>* b) {
  PutU32(b, o.id);
  PutStr(b, o.name);
  PutStr(b, o.source);
  PutU32(b, static_cast<uint32_t>(o.attributes.size()));
  for (const ObjectAttribute& a : o.attributes) {
    PutStr(b, a.key);
    PutStr(b, a.value);
  }
  PutU32(b, static_cast<uint32_t>(o.mesh.vertex_count()));
  PutBytes(b, o.mesh.vertices.data(), 8 * o.mesh.vertices.size());
  PutU32(b, static_cast<uint32_t>(o.mesh.triangle_count()));
  PutBytes(b, o.mesh.triangles.data(), 4 * o.mesh.triangles.size());
}

Result<std::unique_ptr<SceneSource>> OpenExchangeSpill(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return Status::IOError(path + ": " + std::strerror(errno));
  return std::unique_ptr<SceneSource>(std::make_unique<SpillSource>(path, f));
}

}  // namespace mktree
