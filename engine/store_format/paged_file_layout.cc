// The paged-file backend's store layout (docs/store_format.md), on a paged file (storage/paged_file_store.h):
//   [0, P)                       header page (P = MemPage bytes; fixed fields in the first 512 bytes)
//   [P * (1 + i), P * (2 + i))   page i: the leaf pages, then the object record pages
//   then the sections, back to back: nodes, split nodes, leaves, leaf id digests, record directory,
//   sources, stats JSON, leaf filter, codec dictionary.
// The header is written last, at Commit, so an unfinished file has a zero header and is refused.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <type_traits>

#include "engine/store_format/record_codec.h"
#include "engine/store_format/store_backend.h"
#include "storage/byte_io.h"
#include "storage/file_util.h"
#include "storage/paged_file_store.h"

namespace mktree {

using storage_internal::ErrnoText;
using storage_internal::Get;
using storage_internal::PreadFull;
using storage_internal::Put;
using storage_internal::PwriteFull;

namespace {

// 2: the leaf filter holds 10-bit levels in 8 bytes an object; 3: the store frame (an origin in the header,
// boxes relative to it, vertices in each object's local frame); 4: object records in pages after the leaf
// pages (record directory and sources sections instead of name ends and names); 5: each object's leaf in
// its record, and a section of leaf id digests instead of the object leaves (u32 an object, in RAM); 6: a
// codec dictionary section (zstd, shared by the entries).
constexpr uint32_t kPagedFileVersion = 6;
constexpr uint32_t kFixedHeaderBytes = 512;  // the smallest page the builder accepts
constexpr uint32_t kParamsOffset = 16;
constexpr uint32_t kSectionCount = 9;
constexpr uint32_t kSectionTableOffset = 80;
constexpr uint32_t kHeaderChecksumOffset = kSectionTableOffset + kSectionCount * kSectionEntryBytes;  // 296
constexpr uint32_t kOriginOffset = kHeaderChecksumOffset + 8;  // 304: 3 x f64
static_assert(kOriginOffset + 24 <= kFixedHeaderBytes);
static_assert(kParamsOffset + kParamsRecordBytes <= 48);

const char* const kSectionNames[kSectionCount] = {"nodes",           "split nodes",      "leaves",
                                                  "leaf id digests", "record directory", "sources",
                                                  "stats JSON",      "leaf filter",      "codec dictionary"};

// Whether records of S are encoded as their bytes in RAM (little-endian host, storage/byte_io.h): each
// named field where the encoding puts it and the record as long as its encoding, so that reserved fields
// fall on padding. The tree's sections are, and are read straight into their records.
consteval bool EncodedAsInRam(const RecordSchema& s) {
  size_t at = 0;
  for (const RecordField& f : s.fields) {
    if (f.name != nullptr && f.offset != at) return false;
    at += f.bytes();
  }
  return at == s.ram_bytes;
}
static_assert(EncodedAsInRam(kNodeRecord) && EncodedAsInRam(kSplitNodeRecord) && EncodedAsInRam(kLeafRecord));

// Reads a section of records of schema S straight into *out (no encoded copy of the section). The bytes are
// not checksummed yet: CheckLabels once they are.
template <const RecordSchema& S, typename T>
Status ReadRecordSection(SectionReader& r, const std::string& path, std::vector<T>* out) {
  static_assert(sizeof(T) == S.ram_bytes && std::is_trivially_copyable_v<T> && EncodedAsInRam(S));
  const uint64_t each = S.encoded_bytes();
  if (r.bytes() % each != 0)
    return Status::Corruption(path + ": " + S.what + " section size " + std::to_string(r.bytes()) +
                              " is not a multiple of its record size " + std::to_string(each));
  out->assign(r.bytes() / each, T{});
  return r.Read(out->data(), r.bytes());
}
// The labelled fields of records read by ReadRecordSection, checked as DecodeRecords does.
template <const RecordSchema& S, typename T>
Status CheckLabels(const std::string& path, const std::vector<T>& records) {
  if (records.empty()) return Status::Ok();  // data() may be null: no offset from it
  for (const RecordField& f : S.fields) {
    if (f.name == nullptr || f.labels.empty()) continue;
    const auto* p = reinterpret_cast<const uint8_t*>(records.data()) + f.offset;
    for (size_t i = 0; i < records.size(); ++i, p += sizeof(T))
      if (*p >= f.labels.size())
        return Status::Corruption(path + ": " + S.what + " " + f.name + " out of range");
  }
  return Status::Ok();
}

uint64_t HeaderChecksum(const uint8_t* header_page, uint64_t mem_page) {
  // XXH3 of the whole header page with its checksum field taken as zero.
  std::vector<uint8_t> copy(header_page, header_page + mem_page);
  std::memset(copy.data() + kHeaderChecksumOffset, 0, 8);
  return Checksum(copy);
}

class PagedFileWriter : public StoreWriter::Impl {
 public:
  PagedFileWriter(std::string path, std::unique_ptr<PagedFileStore> store)
      : path_(std::move(path)), store_(std::move(store)) {}
  PageStore& pages() override { return *store_; }
  void Abort() override { (void)store_->Close(); }

  Status Finish(const StoreContents& c) override {
    const uint64_t mem_page = store_->page_bytes();
    // Sections are encoded one at a time, each freed once written: the tree and object table are in RAM
    // already, and at 10M objects an encoded copy of everything would be the build's peak.
    auto encode = [&c](uint32_t i) -> std::vector<uint8_t> {
      switch (i) {
        case 0:
          return EncodeNodes(c.tree.nodes);
        case 1:
          return EncodeSplitNodes(c.tree.split_nodes);
        case 2:
          return EncodeLeaves(c.tree.leaves);
        case 3:
          return EncodeLeafDigests(c.objects);
        case 4:
          return EncodeRecordDirectory(c.objects.record_directory);
        case 5:
          return EncodeSources(c.objects.sources);
        case 6:
          return std::vector<uint8_t>(c.stats_json.begin(), c.stats_json.end());
        case 7:
          return c.tree.leaf_filter;
        default:
          return c.codec.dictionary ? c.codec.dictionary->bytes() : std::vector<uint8_t>();
      }
    };

    std::vector<uint8_t> header(mem_page, 0);
    uint8_t* h = header.data();
    std::memcpy(h, kPagedFileMagic, 8);
    Put<uint32_t>(h + 8, kPagedFileVersion);
    Put<uint32_t>(h + 12, kFixedHeaderBytes);
    const std::vector<uint8_t> params = EncodeParams(c.params, c.codec);
    std::memcpy(h + kParamsOffset, params.data(), params.size());
    Put<uint64_t>(h + 48, store_->page_count());
    Put<uint64_t>(h + 56, c.objects.size());
    Put<uint32_t>(h + 72, kSectionCount);
    for (int i = 0; i < 3; ++i) Put<double>(h + kOriginOffset + 8 * i, c.tree.origin[i]);

    auto end = WriteSections(store_->fd(), store_->end_of_pages(), kSectionCount, encode,
                             h + kSectionTableOffset, path_, store_->ops());
    if (!end.ok()) return end.status();
    const uint64_t offset = *end;
    Put<uint64_t>(h + 64, offset);  // file bytes
    Put<uint64_t>(h + kHeaderChecksumOffset, HeaderChecksum(h, mem_page));
    FileOps& ops = store_->ops();
    if (ops.Ftruncate(store_->fd(), offset) != 0)
      return Status::IOError(path_ + ": truncate: " + ErrnoText(errno));
    // Data first, then the header that makes it a store.
    if (ops.Fsync(store_->fd()) != 0) return Status::IOError(path_ + ": fsync: " + ErrnoText(errno));
    MKTREE_RETURN_IF_ERROR(PwriteFull(store_->fd(), h, mem_page, 0, path_, ops));
    if (ops.Fsync(store_->fd()) != 0) return Status::IOError(path_ + ": fsync: " + ErrnoText(errno));
    return store_->Close();
  }

 private:
  std::string path_;
  std::unique_ptr<PagedFileStore> store_;
};

}  // namespace

Result<std::unique_ptr<StoreWriter::Impl>> CreatePagedFileWriter(const std::string& temp_path,
                                                                 const BuildParams& params, FileOps& ops) {
  auto store = PagedFileStore::Create(temp_path, params.mem_page(), ops);
  if (!store.ok()) return store.status();
  return std::unique_ptr<StoreWriter::Impl>(new PagedFileWriter(temp_path, std::move(store).value()));
}

Result<OpenedStore> OpenPagedFile(const std::string& path, const ReadOptions& opts) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return Status::NotFound(path + ": no such file");
    return Status::IOError(path + ": open: " + ErrnoText(errno));
  }
  // Closes fd on every error path; released to the store at the end.
  struct FdGuard {
    int fd;
    ~FdGuard() {
      if (fd >= 0) ::close(fd);
    }
  } guard{fd};
  OpenedStore out;
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };

  auto size_or = storage_internal::FileSize(fd, path);
  if (!size_or.ok()) return size_or.status();
  const uint64_t size = *size_or;
  if (size < kFixedHeaderBytes)
    return bad("truncated (" + std::to_string(size) + " bytes): not a complete mktree store");
  uint8_t fixed[kFixedHeaderBytes];
  MKTREE_RETURN_IF_ERROR(PreadFull(fd, fixed, kFixedHeaderBytes, 0, path));
  if (std::memcmp(fixed, kPagedFileMagic, 8) != 0) return bad("not an mktree paged-file store (bad magic)");
  const uint32_t version = Get<uint32_t>(fixed + 8);
  if (version != kPagedFileVersion)
    return storage_internal::UnsupportedFormatVersion(path, "paged-file", version, kPagedFileVersion);
  Status st = DecodeParams(std::span<const uint8_t>(fixed + kParamsOffset, kParamsRecordBytes),
                           &out.contents.params, &out.contents.codec);
  if (!st.ok()) return bad("header: " + st.message());
  const uint64_t mem_page = out.contents.params.mem_page();
  // The header page holds the fixed header (the writer refuses smaller pages): reading a smaller one as
  // a header page would run past its end.
  if (mem_page < kFixedHeaderBytes)
    return bad("header: page size " + std::to_string(mem_page) + " is smaller than the " +
               std::to_string(kFixedHeaderBytes) + "-byte header");
  if (size < mem_page)
    return bad("truncated (" + std::to_string(size) + " bytes, shorter than its header page)");
  std::vector<uint8_t> header(mem_page);
  MKTREE_RETURN_IF_ERROR(PreadFull(fd, header.data(), mem_page, 0, path));
  if (Get<uint64_t>(header.data() + kHeaderChecksumOffset) != HeaderChecksum(header.data(), mem_page))
    return bad("header checksum mismatch");
  const uint8_t* h = header.data();
  const uint64_t page_count = Get<uint64_t>(h + 48);
  const uint64_t object_count = Get<uint64_t>(h + 56);
  const uint64_t file_bytes = Get<uint64_t>(h + 64);
  if (Get<uint32_t>(h + 72) != kSectionCount) return bad("unexpected section count");
  if (file_bytes != size)
    return bad("file is " + std::to_string(size) + " bytes but its header says " +
               std::to_string(file_bytes) + (size < file_bytes ? " (truncated)" : " (trailing bytes)"));
  if (page_count > file_bytes / mem_page) return bad("page count larger than the file");

  StoreContents& c = out.contents;
  c.tree.params = c.params;
  for (int i = 0; i < 3; ++i) {
    c.tree.origin[i] = Get<double>(h + kOriginOffset + 8 * i);
    if (!std::isfinite(c.tree.origin[i])) return bad("header: origin is not finite");
  }
  // Each section is read straight into its final structure: open's peak is the structure, not plus a copy
  // of the largest section. Nothing is decoded before every checksum matched (the object table's three
  // sections are small and decoded together at the end).
  std::vector<uint8_t> leaf_digests, directory, sources, dictionary;
  auto whole = [](SectionReader& r, std::vector<uint8_t>* out) {
    out->resize(r.bytes());
    return r.Read(out->data(), r.bytes());
  };
  auto take = [&](size_t i, SectionReader& r) -> Status {
    Status d;
    switch (i) {
      case 0:
        d = ReadRecordSection<kNodeRecord>(r, path, &c.tree.nodes);
        break;
      case 1:
        d = ReadRecordSection<kSplitNodeRecord>(r, path, &c.tree.split_nodes);
        break;
      case 2:
        d = ReadRecordSection<kLeafRecord>(r, path, &c.tree.leaves);
        break;
      case 3:
        d = whole(r, &leaf_digests);
        break;
      case 4:
        d = whole(r, &directory);
        break;
      case 5:
        d = whole(r, &sources);
        break;
      case 6: {
        std::vector<uint8_t> json;
        d = whole(r, &json);
        c.stats_json.assign(json.begin(), json.end());
        break;
      }
      case 7:
        d = whole(r, &c.tree.leaf_filter);
        break;
      default:
        d = whole(r, &dictionary);
    }
    return d;
  };
  auto end = ReadSections(fd, h + kSectionTableOffset, kSectionNames, (1 + page_count) * mem_page, file_bytes,
                          path, take);
  if (!end.ok()) return end.status();
  if (*end != file_bytes) return bad("sections do not end at the end of the file");
  // Decoded once every checksum matched.
  MKTREE_RETURN_IF_ERROR(CheckLabels<kNodeRecord>(path, c.tree.nodes));
  MKTREE_RETURN_IF_ERROR(CheckLabels<kSplitNodeRecord>(path, c.tree.split_nodes));
  MKTREE_RETURN_IF_ERROR(CheckLabels<kLeafRecord>(path, c.tree.leaves));
  if (Status d = DecodeObjectTable(object_count, leaf_digests, directory, sources, &c.objects); !d.ok())
    return bad(d.message());
  if (c.objects.size() != object_count) return bad("object table size does not match the header");
  if (Status d = LoadCodecDictionary(std::move(dictionary), &c.codec); !d.ok()) return bad(d.message());
  MKTREE_RETURN_IF_ERROR(ValidateStructure(c.tree, c.objects, page_count, path));

  auto store = std::make_unique<PagedFileStore>(path, fd, mem_page, page_count);
  guard.fd = -1;
  out.notice = store->StartReading(opts.direct_io);
  out.pages = std::move(store);
  return out;
}

}  // namespace mktree
