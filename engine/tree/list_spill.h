// The out-of-core top levels of the MKtree build (BuildMKTree, mktree_builder.h): the key lists of a node
// of more than BuildTuning::ram_node_objects objects live in a spill file, which the node's sweeps read one
// list at a time into a window (SplitChooser::Range) and its list partitions write back. A node small
// enough is loaded into the lists' own storage and built in RAM. The file holds list l's position p at
// (l * n + p) * 4, as RAM does, so a node's range is one stretch of each list; after the six lists come
// stretches 6 and 7 of n positions each, which BuildMKTree and DoneRanges (build_state.h) use: the ids and
// the final list 0 wait there for Finish. Its writes and reads go through a FileOps (storage/file_ops.h,
// BuildTuning::spill_file_ops), so that tests inject faults. Internal to engine/tree.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "engine/tree/build_memory.h"
#include "mktree/status.h"
#include "storage/file_ops.h"

namespace mktree::build {

// A failed read or write of the spill file (BuildMKTree turns it into an IOError naming the file).
class SpillError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ListSpill {
 public:
  ListSpill() = default;
  ListSpill(const ListSpill&) = delete;
  ListSpill& operator=(const ListSpill&) = delete;
  ~ListSpill();

  // Creates the file in `dir` ("" : $TMPDIR, else /tmp) for lists of n positions. It has no name
  // (O_TMPFILE) or, where the filesystem refuses that, is unlinked as soon as it is created, so it
  // disappears with its descriptor whatever way the build ends. Written and read through `ops`, which
  // must outlive this.
  Status Open(const std::string& dir, uint32_t n, std::array<BuildVector<uint32_t>, 6>* lists,
              FileOps& ops = DefaultFileOps());
  bool open() const { return fd_ >= 0; }

  // Writes list l's positions [lo, hi) from RAM to the file and gives their RAM back (whole pages inside
  // the range are unmapped, the rest zeroed: a read without Load finds zeros, never stale values).
  void Store(int l, uint32_t lo, uint32_t hi) { StoreAt(l, l, lo, hi); }
  // The same, into stretch `at` of the file (6 or 7: after the lists).
  void StoreAt(int l, int at, uint32_t lo, uint32_t hi);
  // Reads list l's positions [lo, hi) from the file into RAM.
  void Load(int l, uint32_t lo, uint32_t hi) { Read(l, lo, hi, (*lists_)[l].data() + lo); }
  // List l's positions [lo, hi) from the file to `to` / from `from` to the file.
  void Read(int l, uint32_t lo, uint32_t hi, uint32_t* to);
  void Write(int l, uint32_t lo, uint32_t hi, const uint32_t* from);
  uint64_t bytes_written() const { return written_.load(std::memory_order_relaxed); }

 private:
  int fd_ = -1;
  FileOps* ops_ = &DefaultFileOps();
  std::string where_;  // names the file in errors
  uint32_t n_ = 0;
  std::array<BuildVector<uint32_t>, 6>* lists_ = nullptr;
  void Evict(int l, uint32_t lo, uint32_t hi);
  std::atomic<uint64_t> written_{0};
};

}  // namespace mktree::build
