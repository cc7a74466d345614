// Internal to engine/store_format/: what a store backend implements (paged_file_layout.cc, hdf5_layout.cc).
#pragma once

#include <memory>
#include <string>

#include "engine/store_format/store_file.h"

namespace mktree {

// Everything a store holds besides leaf pages.
struct StoreContents {
  BuildParams params;
  CodecOptions codec;
  MKTree tree;
  ObjectTable objects;
  std::string stats_json;
};

class StoreWriter::Impl {
 public:
  virtual ~Impl() = default;
  virtual PageStore& pages() = 0;
  // Writes everything but the pages, makes the file durable (fsync) and closes it. Not the rename.
  virtual Status Finish(const StoreContents& c) = 0;
  // Closes the file without finishing it (the caller removes it).
  virtual void Abort() = 0;
};

// Loads a store's codec dictionary section into c->dictionary (none when `bytes` is empty). Corruption,
// without the store's name, when the bytes are not a zstd dictionary or the store's codec is not zstd.
Status LoadCodecDictionary(std::vector<uint8_t> bytes, CodecOptions* c);

// `ops` makes every write, truncation and fsync of the file (fault injection in tests).
Result<std::unique_ptr<StoreWriter::Impl>> CreatePagedFileWriter(const std::string& temp_path,
                                                                 const BuildParams& params, FileOps& ops);
Result<std::unique_ptr<StoreWriter::Impl>> CreateHdf5Writer(const std::string& temp_path,
                                                            const BuildParams& params, FileOps& ops);

struct OpenedStore {
  std::unique_ptr<PageStore> pages;
  StoreContents contents;
  std::string notice;
};
Result<OpenedStore> OpenPagedFile(const std::string& path, const ReadOptions& opts);
Result<OpenedStore> OpenHdf5(const std::string& path, const ReadOptions& opts);

// File magics: the first 8 bytes of each backend's file.
inline constexpr char kPagedFileMagic[8] = {'M', 'K', 'T', 'R', 'E', 'E', 'P', 'F'};
inline constexpr unsigned char kHdf5Signature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};

}  // namespace mktree
