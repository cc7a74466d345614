#include "engine/shard/manifest.h"

#include <fcntl.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "storage/atomic_file.h"
#include "storage/byte_io.h"
#include "storage/file_util.h"

namespace mktree {

using storage_internal::ByteReader;
using storage_internal::ByteWriter;

namespace {

constexpr char kIdsMagic[8] = {'M', 'K', 'T', 'S', 'H', 'I', 'D', 'S'};
constexpr uint32_t kIdsVersion = 1;
constexpr uint64_t kMaxManifestBytes = uint64_t{1} << 28;
constexpr uint32_t kMaxName = 4096;
constexpr uint64_t kFingerprintSpan = 64 * 1024;

struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

// The whole file, at most max_bytes.
Result<std::vector<uint8_t>> ReadWhole(const std::string& path, uint64_t max_bytes) {
  Fd f;
  f.fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (f.fd < 0) {
    const int err = errno;
    if (err == ENOENT) return Status::NotFound(path + ": no such file");
    return Status::IOError(path + ": " + storage_internal::ErrnoText(err));
  }
  MKTREE_ASSIGN_OR_RETURN(const uint64_t size, storage_internal::FileSize(f.fd, path));
  if (size > max_bytes) return Status::Corruption(path + ": " + std::to_string(size) + " bytes: too large");
  std::vector<uint8_t> bytes(size);
  MKTREE_RETURN_IF_ERROR(storage_internal::PreadFull(f.fd, bytes.data(), size, 0, path));
  return bytes;
}

Status WriteAtomically(const std::string& path, const std::vector<uint8_t>& bytes,
                       FileOps& ops = DefaultFileOps()) {
  MKTREE_ASSIGN_OR_RETURN(auto file, AtomicFile::Create(path, ops));
  MKTREE_RETURN_IF_ERROR(file->Write(bytes.data(), bytes.size()));
  return file->Commit();
}

void AppendChecksum(std::vector<uint8_t>* bytes) {
  const uint64_t sum = XXH3_64bits(bytes->data(), bytes->size());
  ByteWriter(bytes).Put<uint64_t>(sum);
}

bool ChecksumOk(const std::vector<uint8_t>& bytes) {
  if (bytes.size() < 8) return false;
  return XXH3_64bits(bytes.data(), bytes.size() - 8) ==
         storage_internal::Get<uint64_t>(bytes.data() + bytes.size() - 8);
}

void PutName(ByteWriter& w, const std::string& s) {
  w.Put<uint32_t>(static_cast<uint32_t>(s.size()));
  w.PutBytes(s.data(), s.size());
}

bool GetName(ByteReader& r, const uint8_t* base, size_t size, std::string* out) {
  const uint32_t n = r.Get<uint32_t>();
  if (!r.ok() || n == 0 || n > kMaxName || n > r.remaining()) return false;
  const size_t at = size - r.remaining();
  out->assign(reinterpret_cast<const char*>(base + at), n);
  for (uint32_t i = 0; i < n; ++i) r.Get<uint8_t>();
  // A plain file name: no directory part, nothing that leaves the manifest's directory.
  return out->find('/') == std::string::npos && out->find('\0') == std::string::npos && *out != "." &&
         *out != "..";
}

}  // namespace

bool IsManifestFile(const std::string& path) {
  char head[8];
  auto got = storage_internal::ReadPrefix(path, head, sizeof head);
  return got.ok() && *got == sizeof head && std::memcmp(head, kManifestMagic, sizeof head) == 0;
}

std::string ShardStorePath(const std::string& manifest, uint32_t shard) {
  return manifest + ".shard-" + std::to_string(shard) + ".mkt";
}
std::string ShardIdsPath(const std::string& manifest, uint32_t shard) {
  return manifest + ".shard-" + std::to_string(shard) + ".ids";
}
std::string ShardFilePath(const std::string& manifest, const std::string& name) {
  return (std::filesystem::path(manifest).parent_path() / name).string();
}

Status WriteManifest(const std::string& path, const Manifest& m, FileOps& ops) {
  std::vector<uint8_t> b;
  ByteWriter w(&b);
  w.PutBytes(kManifestMagic, sizeof kManifestMagic);
  w.Put<uint32_t>(kManifestVersion);
  w.Put<uint32_t>(m.top.shard_count);
  w.Put<uint64_t>(m.build_id);
  w.Put<uint64_t>(m.objects);
  for (int i = 0; i < 3; ++i) w.Put<double>(m.origin[i]);
  w.Put<uint32_t>(static_cast<uint32_t>(m.top.nodes.size()));
  for (const TopNode& t : m.top.nodes) {
    w.Put<uint8_t>(t.axis);
    w.Put<uint8_t>(static_cast<uint8_t>(t.key));
    w.Put<uint16_t>(0);
    w.Put<double>(t.cut);
    w.Put<uint32_t>(t.child[0]);
    w.Put<uint32_t>(t.child[1]);
    w.Put<uint32_t>(t.shard);
  }
  for (const ShardEntry& s : m.shards) {
    for (const ShardFileInfo* f : {&s.store, &s.ids}) {
      PutName(w, f->name);
      w.Put<uint64_t>(f->bytes);
      w.Put<uint64_t>(f->fingerprint);
    }
    w.Put<uint64_t>(s.objects);
    for (int i = 0; i < 3; ++i) w.Put<float>(s.box.min[i]);
    for (int i = 0; i < 3; ++i) w.Put<float>(s.box.max[i]);
  }
  AppendChecksum(&b);
  return WriteAtomically(path, b, ops);
}

Result<Manifest> ReadManifest(const std::string& path) {
  MKTREE_ASSIGN_OR_RETURN(const std::vector<uint8_t> b, ReadWhole(path, kMaxManifestBytes));
  auto bad = [&](const std::string& what) {
    return Status::Corruption(path + ": sharded store manifest: " + what);
  };
  if (b.size() < 12 || std::memcmp(b.data(), kManifestMagic, 8) != 0) return bad("bad magic");
  const uint32_t version = storage_internal::Get<uint32_t>(b.data() + 8);
  if (version != kManifestVersion)
    return storage_internal::UnsupportedFormatVersion(path, "sharded store manifest", version,
                                                      kManifestVersion);
  if (!ChecksumOk(b)) return bad("checksum mismatch (truncated or damaged)");
  ByteReader r(b.data() + 12, b.size() - 20);
  const size_t body = b.size() - 8;
  Manifest m;
  m.top.shard_count = r.Get<uint32_t>();
  m.build_id = r.Get<uint64_t>();
  m.objects = r.Get<uint64_t>();
  for (int i = 0; i < 3; ++i) m.origin[i] = r.Get<double>();
  const uint32_t node_count = r.Get<uint32_t>();
  if (!r.ok() || m.top.shard_count == 0 || m.top.shard_count > kMaxShards ||
      node_count != 2 * uint64_t{m.top.shard_count} - 1 || uint64_t{node_count} * 24 > r.remaining())
    return bad("bad header");
  if (!std::isfinite(m.origin.x) || !std::isfinite(m.origin.y) || !std::isfinite(m.origin.z))
    return bad("origin not finite");
  m.top.nodes.resize(node_count);
  for (TopNode& t : m.top.nodes) {
    t.axis = r.Get<uint8_t>();
    t.key = static_cast<ShardKey>(r.Get<uint8_t>());
    r.Get<uint16_t>();
    t.cut = r.Get<double>();
    t.child[0] = r.Get<uint32_t>();
    t.child[1] = r.Get<uint32_t>();
    t.shard = r.Get<uint32_t>();
  }
  MKTREE_RETURN_IF_ERROR(m.top.Validate(path));
  if (uint64_t{m.top.shard_count} * 72 > r.remaining()) return bad("truncated shard table");
  m.shards.resize(m.top.shard_count);
  uint64_t total = 0;
  for (ShardEntry& s : m.shards) {
    for (ShardFileInfo* f : {&s.store, &s.ids}) {
      if (!GetName(r, b.data() + 12, body - 12, &f->name)) return bad("bad shard file name");
      f->bytes = r.Get<uint64_t>();
      f->fingerprint = r.Get<uint64_t>();
    }
    s.objects = r.Get<uint64_t>();
    for (int i = 0; i < 3; ++i) s.box.min[i] = r.Get<float>();
    for (int i = 0; i < 3; ++i) s.box.max[i] = r.Get<float>();
    if (!r.ok()) return bad("truncated shard table");
    if (s.objects == 0 || s.objects > m.objects || s.box.empty()) return bad("bad shard entry");
    total += s.objects;
  }
  if (r.remaining() != 0) return bad("trailing bytes");
  if (total != m.objects) return bad("shard object counts do not add up to the scene's");
  return m;
}

Result<ShardFileInfo> FingerprintFile(const std::string& path) {
  Fd f;
  f.fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (f.fd < 0) {
    const int err = errno;
    if (err == ENOENT) return Status::NotFound(path + ": no such file (a shard of the sharded store)");
    return Status::IOError(path + ": " + storage_internal::ErrnoText(err));
  }
  ShardFileInfo info;
  info.name = std::filesystem::path(path).filename().string();
  MKTREE_ASSIGN_OR_RETURN(info.bytes, storage_internal::FileSize(f.fd, path));
  const uint64_t head = std::min(info.bytes, kFingerprintSpan);
  const uint64_t tail_at = info.bytes - std::min(info.bytes - head, kFingerprintSpan);
  std::vector<uint8_t> buf(head + (info.bytes - tail_at) + 8);
  MKTREE_RETURN_IF_ERROR(storage_internal::PreadFull(f.fd, buf.data(), head, 0, path));
  MKTREE_RETURN_IF_ERROR(
      storage_internal::PreadFull(f.fd, buf.data() + head, info.bytes - tail_at, tail_at, path));
  storage_internal::Put<uint64_t>(buf.data() + buf.size() - 8, info.bytes);
  info.fingerprint = XXH3_64bits(buf.data(), buf.size());
  return info;
}

Status WriteShardIds(const std::string& path, uint64_t build_id, uint32_t shard,
                     const std::vector<ObjectId>& ids, FileOps& ops) {
  std::vector<uint8_t> b;
  b.reserve(40 + 4 * ids.size());
  ByteWriter w(&b);
  w.PutBytes(kIdsMagic, sizeof kIdsMagic);
  w.Put<uint32_t>(kIdsVersion);
  w.Put<uint32_t>(shard);
  w.Put<uint64_t>(build_id);
  w.Put<uint64_t>(ids.size());
  w.PutBytes(ids.data(), 4 * ids.size());
  AppendChecksum(&b);
  return WriteAtomically(path, b, ops);
}

Result<std::vector<ObjectId>> ReadShardIds(const std::string& path, uint64_t build_id, uint32_t shard,
                                           uint64_t total_objects) {
  MKTREE_ASSIGN_OR_RETURN(const std::vector<uint8_t> b, ReadWhole(path, 40 + 4 * total_objects));
  auto bad = [&](const std::string& what) { return Status::Corruption(path + ": shard id file: " + what); };
  if (b.size() < 40 || std::memcmp(b.data(), kIdsMagic, 8) != 0) return bad("bad magic");
  if (storage_internal::Get<uint32_t>(b.data() + 8) != kIdsVersion)
    return storage_internal::UnsupportedFormatVersion(
        path, "shard id file", storage_internal::Get<uint32_t>(b.data() + 8), kIdsVersion);
  if (!ChecksumOk(b)) return bad("checksum mismatch (truncated or damaged)");
  if (storage_internal::Get<uint32_t>(b.data() + 12) != shard)
    return bad("not shard " + std::to_string(shard));
  if (storage_internal::Get<uint64_t>(b.data() + 16) != build_id)
    return bad("from another build of the sharded store");
  const uint64_t n = storage_internal::Get<uint64_t>(b.data() + 24);
  if (b.size() != 40 + 4 * n) return bad("wrong size");
  std::vector<ObjectId> ids(n);
  if (n > 0) std::memcpy(ids.data(), b.data() + 32, 4 * n);
  for (uint64_t i = 0; i < n; ++i)
    if (ids[i] >= total_objects || (i > 0 && ids[i] <= ids[i - 1]))
      return bad("ids not increasing or out of range");
  return ids;
}

std::optional<ObjectId> LocalIdOf(const std::vector<ObjectId>& ids, ObjectId id) {
  auto it = std::lower_bound(ids.begin(), ids.end(), id);
  if (it == ids.end() || *it != id) return std::nullopt;
  return static_cast<ObjectId>(it - ids.begin());
}

}  // namespace mktree
