#include "engine/tree/list_spill.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <vector>

#ifdef __linux__
#include <sys/mman.h>
#endif

#include "storage/file_util.h"

namespace mktree::build {
namespace {

std::string Errno() { return std::strerror(errno); }

}  // namespace

ListSpill::~ListSpill() {
  if (fd_ >= 0) close(fd_);
}

Status ListSpill::Open(const std::string& dir, uint32_t n, std::array<BuildVector<uint32_t>, 6>* lists,
                       FileOps& ops) {
  n_ = n;
  ops_ = &ops;
  lists_ = lists;
  MKTREE_ASSIGN_OR_RETURN(
      storage_internal::UnnamedFile file,
      storage_internal::OpenUnnamedFile(dir, ".mktree-lists-spill", "the tree build's spill file"));
  fd_ = file.fd;
  where_ = std::move(file.where);
  return Status::Ok();
}

void ListSpill::StoreAt(int l, int at, uint32_t lo, uint32_t hi) {
  Write(at, lo, hi, (*lists_)[l].data() + lo);
  Evict(l, lo, hi);
}

void ListSpill::Write(int l, uint32_t lo, uint32_t hi, const uint32_t* from) {
  const char* p = reinterpret_cast<const char*>(from);
  size_t left = size_t{hi - lo} * sizeof(uint32_t);
  uint64_t at = (uint64_t{static_cast<uint32_t>(l)} * n_ + lo) * sizeof(uint32_t);
  while (left > 0) {
    const ssize_t w = ops_->Pwrite(fd_, p, left, at);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) throw SpillError(where_ + ": writing the tree build's spill file: " + Errno());
    p += w, at += w, left -= static_cast<size_t>(w);
  }
  written_.fetch_add(size_t{hi - lo} * sizeof(uint32_t), std::memory_order_relaxed);
}

void ListSpill::Evict(int l, uint32_t lo, uint32_t hi) {
  uint32_t* const data = (*lists_)[l].data();
  // Whole pages inside [lo, hi) hold nothing of another range: unmapped when the list is mapped.
#ifdef __linux__
  if (size_t{n_} * sizeof(uint32_t) >= BuildAllocator<uint32_t>::kMapBytes) {
    constexpr uintptr_t kPage = 4096;
    const uintptr_t b = reinterpret_cast<uintptr_t>(data + lo), e = reinterpret_cast<uintptr_t>(data + hi);
    const uintptr_t first = (b + kPage - 1) & ~(kPage - 1), last = e & ~(kPage - 1);
    if (last > first) {
      madvise(reinterpret_cast<void*>(first), last - first, MADV_DONTNEED);
      std::memset(data + lo, 0, first - b);
      std::memset(reinterpret_cast<void*>(last), 0, e - last);
      return;
    }
  }
#endif
  std::memset(data + lo, 0, size_t{hi - lo} * sizeof(uint32_t));
}

void ListSpill::Read(int l, uint32_t lo, uint32_t hi, uint32_t* to) {
  char* p = reinterpret_cast<char*>(to);
  size_t left = size_t{hi - lo} * sizeof(uint32_t);
  uint64_t at = (uint64_t{static_cast<uint32_t>(l)} * n_ + lo) * sizeof(uint32_t);
  while (left > 0) {
    const ssize_t r = ops_->Pread(fd_, p, left, at);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw SpillError(where_ + ": reading the tree build's spill file: " + Errno());
    if (r == 0) throw SpillError(where_ + ": the tree build's spill file is shorter than written");
    p += r, at += r, left -= static_cast<size_t>(r);
  }
}

}  // namespace mktree::build
