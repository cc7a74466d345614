// The HDF5 backend's store layout (docs/store_format.md): what an mktree store puts in the file, on top of
// the generic HDF5 layer (storage/hdf5_file.h, storage/hdf5_table.h) and the page dataset
// (storage/hdf5_page_store.h: /pages).
//   /tree/nodes, /tree/split_nodes, /tree/leaves   compound datasets of the record schemas (tree_codec.h)
//   /tree/leaf_filter    uint8, 8 per object
//   /pages               the leaf pages, then the object record pages (record_codec.h)
//   /objects/leaf_digest, /objects/record_directory, /objects/sources   the object table's canonical encoding
//   /stats_json          scalar fixed-length string
//   /codec_dictionary    uint8: the zstd dictionary of the entries (empty: none)
//   attributes on /      magic "MKTREE-HDF5" (written last), format_version, build parameters, codec, counts,
//                        and XXH3-64 checksums of the canonical encodings (tree_codec.h) of each part
// Every HDF5 call runs under hdf5::Lock.
#include <hdf5.h>
#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include "engine/store_format/record_codec.h"
#include "engine/store_format/store_backend.h"
#include "engine/tree/page_budget.h"
#include "storage/byte_io.h"
#include "storage/file_util.h"
#include "storage/hdf5_file.h"
#include "storage/hdf5_page_store.h"
#include "storage/hdf5_table.h"

namespace mktree {

using hdf5::ErrorText;
using hdf5::H5Id;
using hdf5::ReadAttr;
using hdf5::ReadFieldAttr;
using hdf5::ReadStringAttr;
using hdf5::StringType;
using hdf5::WriteAttr;
using hdf5::WriteFieldAttr;
using hdf5::WriteStringAttr;

namespace {

constexpr const char* kHdf5Magic = "MKTREE-HDF5";
// 2: the leaf filter holds 10-bit levels in 8 bytes an object; 3: the store frame (the origin attribute,
// boxes relative to it, vertices in each object's local frame), and the object table as its canonical
// encoding (leaf, name_end, names) instead of fixed-length names padded to the longest one; 4: object
// records in pages after the leaf pages (record_directory and sources instead of name_end and names); 5:
// each object's leaf in its record, and leaf_digest (u64 per leaf) instead of leaf (u32 per object); 6:
// codec_dictionary (zstd, shared by the entries).
constexpr uint32_t kHdf5FormatVersion = 6;
constexpr hsize_t kObjectChunkRows = 65536;

constexpr int kChecksumCount = 8;
constexpr const char* kChecksumNames[kChecksumCount] = {
    "checksum_header",  "checksum_nodes",      "checksum_split_nodes", "checksum_leaves",
    "checksum_objects", "checksum_stats_json", "checksum_leaf_filter", "checksum_codec_dictionary"};

// XXH3 of the header fields: parameters, codec, counts, version, origin.
uint64_t HeaderChecksum(const BuildParams& p, const CodecOptions& c, uint64_t pages, uint64_t objects,
                        const Vec3d& origin) {
  std::vector<uint8_t> b = EncodeParams(p, c);
  storage_internal::ByteWriter w(&b);
  w.Put<uint64_t>(pages);
  w.Put<uint64_t>(objects);
  w.Put<uint32_t>(kHdf5FormatVersion);
  for (int i = 0; i < 3; ++i) w.Put<double>(origin[i]);
  return Checksum(b);
}

// The store frame's origin: an attribute of three doubles.
Status WriteOrigin(hid_t loc, const Vec3d& origin, const std::string& path) {
  const hsize_t n = 3;
  const double v[3] = {origin.x, origin.y, origin.z};
  H5Id space(H5Screate_simple(1, &n, nullptr), H5Sclose);
  H5Id a(H5Acreate2(loc, "origin", H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.ok() || H5Awrite(a.get(), H5T_NATIVE_DOUBLE, v) < 0)
    return Status::IOError(path + ": writing attribute origin: " + ErrorText());
  return Status::Ok();
}
Status ReadOrigin(hid_t loc, Vec3d* origin, const std::string& path) {
  if (H5Aexists(loc, "origin") <= 0) return Status::Corruption(path + ": missing attribute origin");
  H5Id a(H5Aopen(loc, "origin", H5P_DEFAULT), H5Aclose);
  H5Id space(H5Aget_space(a.get()), H5Sclose);
  hsize_t n = 0;
  if (!a.ok() || H5Sget_simple_extent_ndims(space.get()) != 1 ||
      H5Sget_simple_extent_dims(space.get(), &n, nullptr) < 0 || n != 3)
    return Status::Corruption(path + ": attribute origin is not three numbers");
  double v[3];
  if (H5Aread(a.get(), H5T_NATIVE_DOUBLE, v) < 0)
    return Status::Corruption(path + ": reading attribute origin: " + ErrorText());
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(v[i])) return Status::Corruption(path + ": attribute origin is not finite");
    (*origin)[i] = v[i];
  }
  return Status::Ok();
}
// XXH3 of the leaf id digests, record directory and sources table concatenated, streamed part by part.
uint64_t ObjectsChecksum(const ObjectTable& t) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), XXH3_freeState);
  XXH3_64bits_reset(state.get());
  for (const std::vector<uint8_t>& b :
       {EncodeLeafDigests(t), EncodeRecordDirectory(t.record_directory), EncodeSources(t.sources)})
    XXH3_64bits_update(state.get(), b.data(), b.size());
  return XXH3_64bits_digest(state.get());
}

class Hdf5Writer : public StoreWriter::Impl {
 public:
  Hdf5Writer(std::string path, std::unique_ptr<Hdf5PageStore> store)
      : path_(std::move(path)), store_(std::move(store)) {}
  PageStore& pages() override { return *store_; }
  void Abort() override { store_->Abort(); }

  Status Finish(const StoreContents& c) override {
    {
      hdf5::Lock lock;
      Status st = WriteAll(c);
      // An I/O error is the cause of whatever HDF5 said after it.
      if (!store_->IoStatus().ok()) return store_->IoStatus();
      MKTREE_RETURN_IF_ERROR(st);
    }
    // HDF5 does not fsync: the driver does, before it closes the descriptor.
    return store_->Close(/*sync=*/true);
  }

 private:
  Status WriteAll(const StoreContents& c) {
    const hid_t f = store_->file();
    MKTREE_RETURN_IF_ERROR(store_->Trim());
    H5Id tree(H5Gcreate2(f, "tree", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    if (!tree.ok()) return Status::IOError(path_ + ": creating /tree: " + ErrorText());

    // Written straight from the tree's arrays: the schemas' memory types point into its records.
    auto write_table = [&](const char* name, const RecordsView& records) {
      return hdf5::WriteTable(tree.get(), name, records, path_).status();
    };
    MKTREE_RETURN_IF_ERROR(write_table("nodes", Records<kNodeRecord>(c.tree.nodes)));
    MKTREE_RETURN_IF_ERROR(write_table("split_nodes", Records<kSplitNodeRecord>(c.tree.split_nodes)));
    MKTREE_RETURN_IF_ERROR(write_table("leaves", Records<kLeafRecord>(c.tree.leaves)));
    // The leaf filter: 8 uint8 per object (see docs/store_format.md), leaf by leaf.
    MKTREE_RETURN_IF_ERROR(write_table("leaf_filter", Records<kByteColumn>(c.tree.leaf_filter)));
    MKTREE_RETURN_IF_ERROR(store_->IoStatus());

    MKTREE_RETURN_IF_ERROR(WriteObjects(f, c.objects));
    MKTREE_RETURN_IF_ERROR(store_->IoStatus());
    const std::vector<uint8_t> no_dictionary;
    const std::vector<uint8_t>& dictionary = c.codec.dictionary ? c.codec.dictionary->bytes() : no_dictionary;
    MKTREE_RETURN_IF_ERROR(
        hdf5::WriteTable(f, "codec_dictionary", Records<kByteColumn>(dictionary), path_).status());
    MKTREE_RETURN_IF_ERROR(store_->IoStatus());

    {  // stats JSON: a scalar fixed-length string dataset. Not variable-length: HDF5's global heap, where
       // those live, has no checksum, and a damaged heap entry crashes the library on read.
      const std::string& js = c.stats_json;
      H5Id t = StringType(std::max<size_t>(1, js.size()));
      H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
      H5Id d(H5Dcreate2(f, "stats_json", t.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
             H5Dclose);
      std::string padded = js;
      padded.resize(std::max<size_t>(1, js.size()), '\0');
      if (!d.ok() || H5Dwrite(d.get(), t.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, padded.data()) < 0)
        return Status::IOError(path_ + ": writing stats_json: " + ErrorText());
    }

    const uint64_t pages = store_->page_count(), objects = c.objects.size();
    const ParamsRecord params = ToParamsRecord(c.params, c.codec);
    // One encoded section alive at a time (an initializer list would keep every temporary to its end).
    uint64_t sums[kChecksumCount];
    sums[0] = HeaderChecksum(c.params, c.codec, pages, objects, c.tree.origin);
    sums[1] = RecordsChecksum<kNodeRecord>(c.tree.nodes);
    sums[2] = RecordsChecksum<kSplitNodeRecord>(c.tree.split_nodes);
    sums[3] = RecordsChecksum<kLeafRecord>(c.tree.leaves);
    sums[4] = ObjectsChecksum(c.objects);
    sums[5] = Checksum(c.stats_json);
    sums[6] = Checksum(c.tree.leaf_filter);
    sums[7] = Checksum(dictionary);
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "format_version", kHdf5FormatVersion, path_));
    // The parameter record's fields, each an attribute of its name and type; the codec as a word.
    for (const char* field : {"block_size", "blocks_per_page", "balance_r", "split_tree_node_budget"})
      MKTREE_RETURN_IF_ERROR(WriteFieldAttr(f, kParamsRecord, field, &params, path_));
    MKTREE_RETURN_IF_ERROR(
        WriteStringAttr(f, "codec", c.codec.codec == Codec::kZstd ? "zstd" : "none", path_));
    MKTREE_RETURN_IF_ERROR(WriteFieldAttr(f, kParamsRecord, "zstd_level", &params, path_));
    MKTREE_RETURN_IF_ERROR(WriteFieldAttr(f, kParamsRecord, "shuffle", &params, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "page_count", pages, path_));
    MKTREE_RETURN_IF_ERROR(WriteAttr(f, "object_count", objects, path_));
    MKTREE_RETURN_IF_ERROR(WriteOrigin(f, c.tree.origin, path_));
    for (int i = 0; i < kChecksumCount; ++i)
      MKTREE_RETURN_IF_ERROR(WriteAttr(f, kChecksumNames[i], sums[i], path_));
    // Last: the magic that makes the file a store.
    MKTREE_RETURN_IF_ERROR(WriteStringAttr(f, "magic", kHdf5Magic, path_));
    if (H5Fflush(f, H5F_SCOPE_LOCAL) < 0) return Status::IOError(path_ + ": flush: " + ErrorText());
    return store_->IoStatus();
  }

  // /objects: the object table's canonical encoding (tree_codec.h): leaf_digest (uint64 per leaf, chunked
  // with shuffle + deflate), record_directory (uint32 per record page, likewise) and sources (the sources
  // table's bytes, uint8, unfiltered so that its length is bounded by the file's at open).
  Status WriteObjects(hid_t f, const ObjectTable& t) {
    H5Id g(H5Gcreate2(f, "objects", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    if (!g.ok()) return Status::IOError(path_ + ": creating /objects: " + ErrorText());
    auto write = [&](const char* name, const RecordsView& records) -> Status {
      if (records.count == 0 || H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0)
        return hdf5::WriteTable(g.get(), name, records, path_).status();
      const hdf5::TableLayout layout{.chunk_rows = kObjectChunkRows, .deflate = 4, .shuffle = true};
      return hdf5::WriteTable(g.get(), name, records, path_, layout, std::string("/objects/") + name)
          .status();
    };
    MKTREE_RETURN_IF_ERROR(write("leaf_digest", Records<kLeafDigestColumn>(t.leaf_digest)));
    MKTREE_RETURN_IF_ERROR(write("record_directory", Records<kRecordDirectoryColumn>(t.record_directory)));
    const std::vector<uint8_t> sources = EncodeSources(t.sources);
    return hdf5::WriteTable(g.get(), "sources", Records<kByteColumn>(sources), path_).status();
  }

  std::string path_;
  std::unique_ptr<Hdf5PageStore> store_;
};

// Reads /objects of a store of `objects` objects and `pages` pages. Every length is checked before its
// allocation: leaf_digest and record_directory must have at most `pages` elements (a leaf has a page at
// least; ValidateStructure then wants one digest per leaf), sources (unfiltered) at most the file's size.
Status ReadObjects(hid_t f, uint64_t objects, uint64_t pages, uint64_t file_bytes, ObjectTable* t,
                   const std::string& path) {
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };
  if (H5Lexists(f, "objects", H5P_DEFAULT) <= 0) return bad("missing group objects");
  H5Id g(H5Gopen2(f, "objects", H5P_DEFAULT), H5Gclose);
  if (!g.ok()) return bad("objects: " + ErrorText());
  auto open = [&](const char* name, uint64_t max_bytes, H5Id* d) -> Result<uint64_t> {
    if (H5Lexists(g.get(), name, H5P_DEFAULT) <= 0)
      return bad(std::string("missing dataset objects/") + name);
    *d = H5Id(H5Dopen2(g.get(), name, H5P_DEFAULT), H5Dclose);
    if (!d->ok()) return bad(std::string("objects/") + name + ": " + ErrorText());
    const std::string full = std::string("objects/") + name;
    auto n = hdf5::TableLength(d->get(), full.c_str(), max_bytes, path);
    if (!n.ok()) return n.status();
    return static_cast<uint64_t>(*n);
  };
  H5Id digest, directory, sources;
  // leaf_digest and record_directory may be compressed: their lengths are bounded by the counts, not the
  // file.
  MKTREE_ASSIGN_OR_RETURN(const uint64_t n_digest, open("leaf_digest", UINT64_MAX, &digest));
  if (n_digest > pages)
    return bad("objects/leaf_digest has " + std::to_string(n_digest) + " elements for " +
               std::to_string(pages) + " pages");
  MKTREE_ASSIGN_OR_RETURN(const uint64_t n_dir, open("record_directory", UINT64_MAX, &directory));
  if (n_dir > pages)
    return bad("objects/record_directory has " + std::to_string(n_dir) + " elements for " +
               std::to_string(pages) + " pages");
  MKTREE_ASSIGN_OR_RETURN(const uint64_t n_sources, open("sources", file_bytes, &sources));
  t->count = objects;
  t->leaf_digest.resize(n_digest);
  t->record_directory.resize(n_dir);
  if (n_digest > 0)
    MKTREE_RETURN_IF_ERROR(
        hdf5::ReadRows<kLeafDigestColumn>(digest.get(), &t->leaf_digest, path, "objects/leaf_digest"));
  if (n_dir > 0)
    MKTREE_RETURN_IF_ERROR(hdf5::ReadRows<kRecordDirectoryColumn>(directory.get(), &t->record_directory, path,
                                                                  "objects/record_directory"));
  std::vector<uint8_t> bytes(n_sources);
  if (n_sources > 0)
    MKTREE_RETURN_IF_ERROR(hdf5::ReadRows<kByteColumn>(sources.get(), &bytes, path, "objects/sources"));
  Status st = DecodeSources(bytes, &t->sources);
  return st.ok() ? st : bad("objects/sources: " + st.message());
}

}  // namespace

Result<std::unique_ptr<StoreWriter::Impl>> CreateHdf5Writer(const std::string& temp_path,
                                                            const BuildParams& params, FileOps& ops) {
  auto store = Hdf5PageStore::Create(temp_path, params.mem_page(), ops);
  if (!store.ok()) return store.status();
  return std::unique_ptr<StoreWriter::Impl>(new Hdf5Writer(temp_path, std::move(store).value()));
}

Result<OpenedStore> OpenHdf5(const std::string& path, const ReadOptions& opts) {
  hdf5::Lock lock;
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };
  H5Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) return bad("HDF5 cannot open it (" + ErrorText() + "): truncated or damaged");
  const hid_t f = file.get();
  hsize_t file_bytes = 0;
  if (H5Fget_filesize(f, &file_bytes) < 0) return bad("HDF5 cannot tell its size (" + ErrorText() + ")");
  if (H5Aexists(f, "magic") <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return bad("an HDF5 file, but not an mktree store (no magic attribute)");
  }
  auto magic = ReadStringAttr(f, "magic", path);
  if (!magic.ok()) return magic.status();
  if (*magic != kHdf5Magic) return bad("an HDF5 file, but not an mktree store (magic \"" + *magic + "\")");
  uint32_t version = 0;
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "format_version", &version, path));
  if (version != kHdf5FormatVersion)
    return storage_internal::UnsupportedFormatVersion(path, "HDF5 store", version, kHdf5FormatVersion);
  OpenedStore out;
  StoreContents& c = out.contents;
  uint64_t page_count = 0, object_count = 0;
  ParamsRecord params;
  for (const char* field :
       {"block_size", "blocks_per_page", "balance_r", "split_tree_node_budget", "zstd_level", "shuffle"})
    MKTREE_RETURN_IF_ERROR(ReadFieldAttr(f, kParamsRecord, field, &params, path));
  c.params.block_size = params.block_size;
  c.params.blocks_per_page = params.blocks_per_page;
  c.params.balance_r = params.balance_r;
  c.params.split_tree_node_budget = params.split_tree_node_budget;
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "page_count", &page_count, path));
  MKTREE_RETURN_IF_ERROR(ReadAttr(f, "object_count", &object_count, path));
  auto codec = ReadStringAttr(f, "codec", path);
  if (!codec.ok()) return codec.status();
  if (*codec != "zstd" && *codec != "none") return bad("unknown codec \"" + *codec + "\"");
  c.codec.codec = *codec == "zstd" ? Codec::kZstd : Codec::kNone;
  c.codec.zstd_level = params.zstd_level;
  c.codec.shuffle = params.shuffle != 0;
  uint64_t sums[kChecksumCount];
  for (int i = 0; i < kChecksumCount; ++i)
    MKTREE_RETURN_IF_ERROR(ReadAttr(f, kChecksumNames[i], &sums[i], path));
  MKTREE_RETURN_IF_ERROR(ReadOrigin(f, &c.tree.origin, path));
  if (HeaderChecksum(c.params, c.codec, page_count, object_count, c.tree.origin) != sums[0])
    return bad("header checksum mismatch");
  BuildParams check_params;
  CodecOptions check_codec;
  Status st = DecodeParams(EncodeParams(c.params, c.codec), &check_params, &check_codec);
  if (!st.ok()) return bad(st.message());
  const uint64_t mem_page = c.params.mem_page();
  // Counts bounded by the file before anything is sized by them (a checksum is no proof: it is not a MAC).
  // Every page is stored whole and unfiltered, and every object's leaf entry (at least its header) is in a
  // page.
  if (page_count > file_bytes / mem_page)
    return bad(std::to_string(page_count) + " pages of " + std::to_string(mem_page) +
               " bytes do not fit in its " + std::to_string(file_bytes) + " bytes");
  if (object_count > page_count * PagePayloadCapacity(mem_page) / kObjectEntryHeaderBytes)
    return bad(std::to_string(object_count) + " objects do not fit in its " + std::to_string(page_count) +
               " pages");

  // The tree: contiguous, unfiltered datasets, each at most the file's size.
  if (H5Lexists(f, "tree", H5P_DEFAULT) <= 0) return bad("missing group /tree");
  H5Id tree(H5Gopen2(f, "tree", H5P_DEFAULT), H5Gclose);
  if (!tree.ok()) return bad("/tree: " + ErrorText());
  // Read straight into the tree's arrays (the schemas' memory types point into its records).
  MKTREE_RETURN_IF_ERROR(hdf5::ReadTable<kNodeRecord>(tree.get(), "nodes", &c.tree.nodes, file_bytes, path));
  MKTREE_RETURN_IF_ERROR(
      hdf5::ReadTable<kSplitNodeRecord>(tree.get(), "split_nodes", &c.tree.split_nodes, file_bytes, path));
  MKTREE_RETURN_IF_ERROR(
      hdf5::ReadTable<kLeafRecord>(tree.get(), "leaves", &c.tree.leaves, file_bytes, path));
  MKTREE_RETURN_IF_ERROR(
      hdf5::ReadTable<kByteColumn>(tree.get(), "leaf_filter", &c.tree.leaf_filter, file_bytes, path));
  if (Checksum(c.tree.leaf_filter) != sums[6]) return bad("leaf_filter checksum mismatch");
  c.tree.params = c.params;
  // A crafted file may hold a label its enumeration does not name: keep it one of the four.
  for (SplitNode& s : c.tree.split_nodes) s.label = static_cast<CellLabel>(static_cast<uint8_t>(s.label) & 3);
  if (RecordsChecksum<kNodeRecord>(c.tree.nodes) != sums[1]) return bad("nodes checksum mismatch");
  if (RecordsChecksum<kSplitNodeRecord>(c.tree.split_nodes) != sums[2])
    return bad("split_nodes checksum mismatch");
  if (RecordsChecksum<kLeafRecord>(c.tree.leaves) != sums[3]) return bad("leaves checksum mismatch");

  MKTREE_RETURN_IF_ERROR(ReadObjects(f, object_count, page_count, file_bytes, &c.objects, path));
  if (ObjectsChecksum(c.objects) != sums[4]) return bad("objects checksum mismatch");
  {
    if (H5Lexists(f, "stats_json", H5P_DEFAULT) <= 0) return bad("missing dataset stats_json");
    H5Id d(H5Dopen2(f, "stats_json", H5P_DEFAULT), H5Dclose);
    if (!d.ok()) return bad("stats_json: " + ErrorText());
    H5Id dt(H5Dget_type(d.get()), H5Tclose);
    H5Id space(H5Dget_space(d.get()), H5Sclose);
    if (H5Tget_class(dt.get()) != H5T_STRING || H5Tis_variable_str(dt.get()) != 0 ||
        H5Sget_simple_extent_type(space.get()) != H5S_SCALAR)
      return bad("stats_json is not a fixed-length string");
    const size_t n = H5Tget_size(dt.get());
    if (n == 0) return bad("stats_json has no valid type");
    if (n > file_bytes)
      return bad("stats_json claims " + std::to_string(n) + " bytes, more than the file's " +
                 std::to_string(file_bytes));
    H5Id t = StringType(n);
    std::string js(n, '\0');
    if (H5Dread(d.get(), t.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, js.data()) < 0)
      return bad("reading stats_json: " + ErrorText());
    js.resize(strnlen(js.data(), n));
    c.stats_json = std::move(js);
  }
  if (Checksum(c.stats_json) != sums[5]) return bad("stats_json checksum mismatch");
  {
    std::vector<uint8_t> dictionary;
    MKTREE_RETURN_IF_ERROR(
        hdf5::ReadTable<kByteColumn>(f, "codec_dictionary", &dictionary, file_bytes, path));
    if (Checksum(dictionary) != sums[7]) return bad("codec_dictionary checksum mismatch");
    if (Status d = LoadCodecDictionary(std::move(dictionary), &c.codec); !d.ok()) return bad(d.message());
  }

  // The pages dataset: shape, chunking and filters as we wrote them.
  auto pages = Hdf5PageStore::Open(path, std::move(file), mem_page, page_count);
  if (!pages.ok()) return pages.status();
  MKTREE_RETURN_IF_ERROR(ValidateStructure(c.tree, c.objects, page_count, path));
  if (opts.direct_io)
    out.notice = path + ": direct I/O is not supported by the HDF5 backend; using buffered reads";
  out.pages = std::move(pages).value();
  return out;
}

}  // namespace mktree
