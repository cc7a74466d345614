#include "engine/viz/level_export.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "engine/store_format/leaf_source.h"
#include "engine/viz/clash_render.h"
#include "engine/viz/spool_file.h"

namespace mktree {

static_assert(std::endian::native == std::endian::little,
              "PLY and GLB are written as little-endian raw memory");

const uint32_t kBoxTriangles[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                    2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};

void BoxCorners(const Box3f& box, float out[24]) {
  for (int i = 0; i < 8; ++i) {
    out[3 * i + 0] = (i & 1) ? box.max[0] : box.min[0];
    out[3 * i + 1] = (i & 2) ? box.max[1] : box.min[1];
    out[3 * i + 2] = (i & 4) ? box.max[2] : box.min[2];
  }
}

Result<ExportFormat> ExportFormatFor(const std::string& path) {
  const size_t dot = path.rfind('.');
  std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == "ply") return ExportFormat::kPly;
  if (ext == "glb") return ExportFormat::kGlb;
  return Status::InvalidArgument(path + ": unknown export format (use .ply or .glb)");
}

namespace {

// Shortest text that reads back to the same double.
std::string Num(double v) {
  char b[32];
  return std::string(b, std::to_chars(b, b + sizeof b, v).ptr);
}

// What the groups are called and coloured: the level-k groups (GroupIndex) or the clash classes (ClashMark).
struct Palette {
  std::array<Rgb, kLevelGroups> colour;
  std::array<std::string, kLevelGroups> name;
  std::string comment;    // the PLY comment's colouring
  std::string generator;  // in the glTF asset's generator
};

Palette LevelPalette(int level) {
  Palette p;
  for (int g = 0; g < kLevelGroups; ++g) {
    p.colour[g] = GroupColour(static_cast<LevelGroup>(g));
    p.name[g] = GroupName(static_cast<LevelGroup>(g));
  }
  p.comment = "level " + std::to_string(level) +
              " colouring: blue Sn1 side, red Sn2 side, green overlap set Sm, grey leaf at depth <= " +
              std::to_string(level);
  p.generator = "level " + std::to_string(level);
  return p;
}

Palette ClashPalette() {
  static_assert(kClashMarks == kLevelGroups);
  Palette p;
  for (int c = 0; c < kClashMarks; ++c) {
    p.colour[c] = ClashColour(static_cast<ClashMark>(c));
    p.name[c] = c == 0 ? "no_clash" : ClashMarkName(static_cast<ClashMark>(c));
  }
  p.comment =
      "clashes: red hard, orange touch, yellow clearance (worst class of each object), grey in no pair";
  p.generator = "clashes";
  return p;
}

// Where exported objects go: one call per object, then Finish.
class GeometrySink {
 public:
  virtual ~GeometrySink() = default;
  virtual Status Add(int g, const float* xyz, uint32_t vertices, const uint32_t* tris,
                     uint32_t triangles) = 0;
  virtual Status Finish(AtomicFile* out) = 0;
};

Status SpoolError(const std::string& path) {
  return Status::IOError(path + ": writing a scratch file failed");
}

// PLY: vertices stream to the output after a header whose counts are patched at the end; faces (which
// PLY wants after all vertices) go to a scratch file that is appended.
class PlySink final : public GeometrySink {
 public:
  static Result<std::unique_ptr<PlySink>> Create(AtomicFile* out, const Palette& palette,
                                                 const Vec3d& origin) {
    auto faces = OpenSpoolFile(out->target());
    if (!faces.ok()) return faces.status();
    auto sink = std::unique_ptr<PlySink>(new PlySink(out, std::move(*faces), palette));
    std::string h = "ply\nformat binary_little_endian 1.0\ncomment mktree export: " + palette.comment +
                    "\ncomment origin " + Num(origin.x) + " " + Num(origin.y) + " " + Num(origin.z) +
                    " (world = vertex + origin)\nelement vertex ";
    sink->vertex_count_at_ = h.size();
    h += std::string(kDigits, '0');
    h += "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
         "property uchar blue\nelement face ";
    sink->face_count_at_ = h.size();
    h += std::string(kDigits, '0');
    h += "\nproperty list uchar uint vertex_indices\nend_header\n";
    MKTREE_RETURN_IF_ERROR(out->Write(h.data(), h.size()));
    return sink;
  }

  Status Add(int g, const float* xyz, uint32_t nv, const uint32_t* tris, uint32_t nt) override {
    if (vertices_ + nv > std::numeric_limits<uint32_t>::max())
      return Status::InvalidArgument(path_ + ": more than 2^32 - 1 vertices (PLY indices are uint32)");
    const Rgb c = palette_.colour[g];
    buf_.resize(size_t{15} * nv);
    for (uint32_t i = 0; i < nv; ++i) {
      uint8_t* p = buf_.data() + size_t{15} * i;
      std::memcpy(p, xyz + 3 * size_t{i}, 12);
      p[12] = c.r, p[13] = c.g, p[14] = c.b;
    }
    MKTREE_RETURN_IF_ERROR(out_->Write(buf_.data(), buf_.size()));
    buf_.resize(size_t{13} * nt);
    const uint32_t base = static_cast<uint32_t>(vertices_);
    for (uint32_t t = 0; t < nt; ++t) {
      uint8_t* p = buf_.data() + size_t{13} * t;
      p[0] = 3;
      for (int k = 0; k < 3; ++k) {
        const uint32_t idx = base + tris[3 * size_t{t} + k];
        std::memcpy(p + 1 + 4 * k, &idx, 4);
      }
    }
    if (!buf_.empty() && std::fwrite(buf_.data(), 1, buf_.size(), faces_.get()) != buf_.size())
      return SpoolError(path_);
    vertices_ += nv;
    faces_count_ += nt;
    return Status::Ok();
  }

  Status Finish(AtomicFile* out) override {
    if (faces_count_ > std::numeric_limits<uint32_t>::max())
      return Status::InvalidArgument(path_ + ": more than 2^32 - 1 triangles");
    MKTREE_RETURN_IF_ERROR(CopySpool(faces_.get(), out));
    MKTREE_RETURN_IF_ERROR(Patch(out, vertex_count_at_, vertices_));
    return Patch(out, face_count_at_, faces_count_);
  }

 private:
  static constexpr int kDigits = 10;  // up to 2^32 - 1, zero-padded: PLY readers parse counts as integers
  PlySink(AtomicFile* out, FilePtr faces, const Palette& palette)
      : path_(out->target()), faces_(std::move(faces)), out_(out), palette_(palette) {}

  static Status Patch(AtomicFile* out, size_t at, uint64_t value) {
    char digits[kDigits + 1];
    std::snprintf(digits, sizeof digits, "%0*llu", kDigits, static_cast<unsigned long long>(value));
    return out->WriteAt(at, digits, kDigits);
  }

  std::string path_;
  FilePtr faces_;
  AtomicFile* out_ = nullptr;
  Palette palette_;
  std::vector<uint8_t> buf_;
  uint64_t vertices_ = 0, faces_count_ = 0;
  size_t vertex_count_at_ = 0, face_count_at_ = 0;
};

double SrgbToLinear(uint8_t c) {
  const double s = c / 255.0;
  return s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4);
}

// GLB: per group, positions and indices spool to their own scratch files; Finish writes the JSON (which
// needs every size) and then the binary chunk from the spools.
class GlbSink final : public GeometrySink {
 public:
  static Result<std::unique_ptr<GlbSink>> Create(const std::string& path, const Palette& palette,
                                                 const Vec3d& origin) {
    auto sink = std::unique_ptr<GlbSink>(new GlbSink(path, palette, origin));
    for (Group& g : sink->groups_) {
      auto p = OpenSpoolFile(path);
      if (!p.ok()) return p.status();
      auto i = OpenSpoolFile(path);
      if (!i.ok()) return i.status();
      g.positions = std::move(*p);
      g.indices = std::move(*i);
    }
    return sink;
  }

  Status Add(int gi, const float* xyz, uint32_t nv, const uint32_t* tris, uint32_t nt) override {
    Group& g = groups_[gi];
    if (g.vertices + nv > std::numeric_limits<uint32_t>::max())
      return Status::InvalidArgument(path_ +
                                     ": more than 2^32 - 1 vertices in one group (glTF uint32 indices)");
    for (size_t i = 0; i < 3 * size_t{nv}; ++i) {
      g.min[i % 3] = std::min(g.min[i % 3], xyz[i]);
      g.max[i % 3] = std::max(g.max[i % 3], xyz[i]);
    }
    if (nv && std::fwrite(xyz, 12, nv, g.positions.get()) != nv) return SpoolError(path_);
    idx_.resize(3 * size_t{nt});
    const uint32_t base = static_cast<uint32_t>(g.vertices);
    for (size_t i = 0; i < idx_.size(); ++i) idx_[i] = base + tris[i];
    if (nt && std::fwrite(idx_.data(), 12, nt, g.indices.get()) != nt) return SpoolError(path_);
    g.vertices += nv;
    g.triangles += nt;
    return Status::Ok();
  }

  Status Finish(AtomicFile* out) override {
    std::string nodes, meshes, materials, views, accessors, scene_nodes;
    uint64_t offset = 0;
    int n = 0;
    for (int gi = 0; gi < kLevelGroups; ++gi) {
      const Group& g = groups_[gi];
      if (g.triangles == 0) continue;
      const Rgb c = palette_.colour[gi];
      const std::string name = palette_.name[gi], sep = n ? "," : "";
      const std::string s = std::to_string(n);
      scene_nodes += sep + s;
      nodes += sep + "{\"name\":\"" + name + "\",\"mesh\":" + s + ",\"translation\":[" + Num(origin_.x) +
               "," + Num(origin_.y) + "," + Num(origin_.z) + "]}";
      meshes += sep + "{\"name\":\"" + name +
                "\",\"primitives\":[{\"attributes\":{\"POSITION\":" + std::to_string(2 * n) +
                "},\"indices\":" + std::to_string(2 * n + 1) + ",\"material\":" + s + ",\"mode\":4}]}";
      materials += sep + "{\"name\":\"" + name + "\",\"doubleSided\":true,\"pbrMetallicRoughness\":{" +
                   "\"baseColorFactor\":[" + Num(SrgbToLinear(c.r)) + "," + Num(SrgbToLinear(c.g)) + "," +
                   Num(SrgbToLinear(c.b)) + ",1],\"metallicFactor\":0,\"roughnessFactor\":0.8}}";
      const uint64_t pos_bytes = 12 * g.vertices, idx_bytes = 12 * g.triangles;
      views += sep + "{\"buffer\":0,\"byteOffset\":" + std::to_string(offset) +
               ",\"byteLength\":" + std::to_string(pos_bytes) +
               ",\"target\":34962},{\"buffer\":0,\"byteOffset\":" + std::to_string(offset + pos_bytes) +
               ",\"byteLength\":" + std::to_string(idx_bytes) + ",\"target\":34963}";
      offset += pos_bytes + idx_bytes;
      accessors +=
          sep + "{\"bufferView\":" + std::to_string(2 * n) +
          ",\"componentType\":5126,\"count\":" + std::to_string(g.vertices) + ",\"type\":\"VEC3\",\"min\":[" +
          Num(g.min[0]) + "," + Num(g.min[1]) + "," + Num(g.min[2]) + "],\"max\":[" + Num(g.max[0]) + "," +
          Num(g.max[1]) + "," + Num(g.max[2]) + "]},{\"bufferView\":" + std::to_string(2 * n + 1) +
          ",\"componentType\":5125,\"count\":" + std::to_string(3 * g.triangles) + ",\"type\":\"SCALAR\"}";
      ++n;
    }
    std::string json = "{\"asset\":{\"version\":\"2.0\",\"generator\":\"mktree export (" +
                       palette_.generator + ")\"},\"scene\":0,\"scenes\":[{\"nodes\":[" + scene_nodes + "]}]";
    if (n) {
      json += ",\"nodes\":[" + nodes + "],\"meshes\":[" + meshes + "],\"materials\":[" + materials +
              "],\"buffers\":[{\"byteLength\":" + std::to_string(offset) + "}],\"bufferViews\":[" + views +
              "],\"accessors\":[" + accessors + "]";
    }
    json += "}";
    json.resize((json.size() + 3) / 4 * 4, ' ');  // chunks are 4-byte aligned; JSON pads with spaces
    // Every piece of the binary chunk is a multiple of 12 bytes, so it needs no padding.
    const uint64_t total = 12 + 8 + json.size() + (n ? 8 + offset : 0);
    if (total > std::numeric_limits<uint32_t>::max())
      return Status::InvalidArgument(
          path_ + ": the GLB would exceed 4 GiB (the format's limit); use .ply or --boxes");
    const uint32_t header[3] = {0x46546C67u, 2, static_cast<uint32_t>(total)};  // "glTF", version 2
    MKTREE_RETURN_IF_ERROR(out->Write(header, sizeof header));
    const uint32_t json_chunk[2] = {static_cast<uint32_t>(json.size()), 0x4E4F534Au};  // "JSON"
    MKTREE_RETURN_IF_ERROR(out->Write(json_chunk, sizeof json_chunk));
    MKTREE_RETURN_IF_ERROR(out->Write(json.data(), json.size()));
    if (n) {
      const uint32_t bin_chunk[2] = {static_cast<uint32_t>(offset), 0x004E4942u};  // "BIN\0"
      MKTREE_RETURN_IF_ERROR(out->Write(bin_chunk, sizeof bin_chunk));
      for (Group& g : groups_) {
        if (g.triangles == 0) continue;
        MKTREE_RETURN_IF_ERROR(CopySpool(g.positions.get(), out));
        MKTREE_RETURN_IF_ERROR(CopySpool(g.indices.get(), out));
      }
    }
    return Status::Ok();
  }

 private:
  struct Group {
    FilePtr positions, indices;
    uint64_t vertices = 0, triangles = 0;
    float min[3] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                    std::numeric_limits<float>::max()};
    float max[3] = {std::numeric_limits<float>::lowest(), std::numeric_limits<float>::lowest(),
                    std::numeric_limits<float>::lowest()};
  };
  GlbSink(std::string path, const Palette& palette, const Vec3d& origin)
      : path_(std::move(path)), palette_(palette), origin_(origin) {}
  std::string path_;
  Palette palette_;
  Vec3d origin_;
  Group groups_[kLevelGroups];
  std::vector<uint32_t> idx_;
};

}  // namespace

Result<ExportReport> ExportLevel(const StoreReader& store, const std::string& out_path,
                                 const ExportOptions& options) {
  if (options.level < 0)
    return Status::InvalidArgument("level " + std::to_string(options.level) + ": levels start at 0");
  const ClashMarks* clashes = options.clashes;
  if (clashes && clashes->worst.size() != store.object_count())
    return Status::InvalidArgument(store.path() + ": the clash marks were read for " +
                                   std::to_string(clashes->worst.size()) + " objects, the store has " +
                                   std::to_string(store.object_count()));
  const Palette palette = clashes ? ClashPalette() : LevelPalette(options.level);
  auto out = AtomicFile::Create(out_path);
  if (!out.ok()) return out.status();
  std::unique_ptr<GeometrySink> sink;
  if (options.format == ExportFormat::kPly) {
    auto s = PlySink::Create(out->get(), palette, store.tree().origin);
    if (!s.ok()) return s.status();
    sink = std::move(*s);
  } else {
    auto s = GlbSink::Create(out_path, palette, store.tree().origin);
    if (!s.ok()) return s.status();
    sink = std::move(*s);
  }
  ExportReport report;
  Mesh mesh;
  std::vector<float> xyz;  // store frame, float32 as both formats hold positions
  float corners[24];
  Status st = ForEachObjectAtLevel(
      store, clashes ? 0 : options.level,
      [&](uint32_t, const ObjectEntryView& e, LevelGroup lg) -> Status {
        const int gi = clashes ? clashes->worst[e.id] : GroupIndex(lg);
        ++report.objects[gi];
        if (options.boxes) {
          BoxCorners(e.box, corners);
          report.vertices[gi] += 8;
          report.triangles[gi] += 12;
          return sink->Add(gi, corners, 8, kBoxTriangles, 12);
        }
        MKTREE_RETURN_IF_ERROR(DecodeStoredMesh(store, e, &mesh));
        const auto nv = static_cast<uint32_t>(mesh.vertex_count()),
                   nt = static_cast<uint32_t>(mesh.triangle_count());
        report.vertices[gi] += nv;
        report.triangles[gi] += nt;
        xyz.assign(mesh.vertices.begin(), mesh.vertices.end());
        return sink->Add(gi, xyz.data(), nv, mesh.triangles.data(), nt);
      },
      options.progress);
  if (!st.ok()) return st;
  MKTREE_RETURN_IF_ERROR(sink->Finish(out->get()));
  report.bytes = (*out)->size();
  MKTREE_RETURN_IF_ERROR((*out)->Commit());
  return report;
}

}  // namespace mktree
