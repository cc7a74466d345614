#include "engine/revision/change_folder.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <thread>

#include "storage/file_util.h"

namespace mktree {

namespace {

namespace fs = std::filesystem;

Result<std::string> ReadAll(int fd, const std::string& path) {
  MKTREE_ASSIGN_OR_RETURN(const uint64_t size, storage_internal::FileSize(fd, path));
  if (size > (uint64_t{1} << 30)) return Status::Corruption(path + ": revision file too large");
  std::string text(size, '\0');
  MKTREE_RETURN_IF_ERROR(storage_internal::PreadFull(fd, text.data(), size, 0, path));
  return text;
}

Status NotKept(const std::string& folder, uint64_t revision) {
  std::string store = folder.substr(0, folder.size() - std::string(".changes").size());
  return Status::NotFound(store + ": revision " + std::to_string(revision) +
                          " is not kept (retired, or never committed)");
}

}  // namespace

std::string ChangesFolder(const std::string& store_path) { return store_path + ".changes"; }

std::string ChangesFile(const std::string& folder, const std::string& name) { return folder + "/" + name; }

Result<std::vector<uint64_t>> ListRevisionNumbers(const std::string& folder) {
  std::vector<uint64_t> out;
  std::error_code ec;
  if (!fs::exists(folder, ec)) return out;
  if (!fs::is_directory(folder, ec)) return Status::Corruption(folder + ": not a folder");
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    uint64_t r = 0;
    if (ParseRevisionFileName(it->path().filename().string(), &r)) out.push_back(r);
  }
  if (ec) return Status::IOError(folder + ": " + ec.message());
  std::sort(out.begin(), out.end());
  return out;
}

Result<RevisionManifest> ReadRevisionFile(const std::string& folder, uint64_t revision) {
  const std::string path = ChangesFile(folder, RevisionFileName(revision));
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return NotKept(folder, revision);
    return Status::IOError(path + ": " + storage_internal::ErrnoText(errno));
  }
  auto text = ReadAll(fd, path);
  ::close(fd);
  if (!text.ok()) return text.status();
  MKTREE_ASSIGN_OR_RETURN(RevisionManifest m, DecodeRevisionManifest(*text, path));
  if (m.revision != revision)
    return Status::Corruption(path + ": holds revision " + std::to_string(m.revision));
  return m;
}

Result<std::unique_ptr<RevisionHold>> RevisionHold::Open(const std::string& folder, uint64_t revision) {
  const std::string path = ChangesFile(folder, RevisionFileName(revision));
  std::unique_ptr<RevisionHold> hold(new RevisionHold());
  hold->fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (hold->fd_ < 0) {
    if (errno == ENOENT) return NotKept(folder, revision);
    return Status::IOError(path + ": " + storage_internal::ErrnoText(errno));
  }
  // The writer holds the lock exclusively only while it unlinks the file: a short wait, never a long one.
  for (int attempt = 0;; ++attempt) {
    if (::flock(hold->fd_, LOCK_SH | LOCK_NB) == 0) break;
    if (errno != EWOULDBLOCK && errno != EINTR)
      return Status::IOError(path + ": lock: " + storage_internal::ErrnoText(errno));
    if (attempt == 1000) return Status::IOError(path + ": lock: held exclusively for over a second");
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  struct stat st;
  if (::fstat(hold->fd_, &st) != 0) return Status::IOError(path + ": " + storage_internal::ErrnoText(errno));
  if (st.st_nlink == 0) return NotKept(folder, revision);
  MKTREE_ASSIGN_OR_RETURN(const std::string text, ReadAll(hold->fd_, path));
  MKTREE_ASSIGN_OR_RETURN(hold->manifest_, DecodeRevisionManifest(text, path));
  if (hold->manifest_.revision != revision)
    return Status::Corruption(path + ": holds revision " + std::to_string(hold->manifest_.revision));
  return hold;
}

RevisionHold::~RevisionHold() {
  if (fd_ >= 0) ::close(fd_);
}

Result<bool> TryRetireRevision(const std::string& folder, uint64_t revision) {
  const std::string path = ChangesFile(folder, RevisionFileName(revision));
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return true;
    return Status::IOError(path + ": " + storage_internal::ErrnoText(errno));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    ::close(fd);
    if (err == EWOULDBLOCK) return false;
    return Status::IOError(path + ": lock: " + storage_internal::ErrnoText(err));
  }
  const int rc = ::unlink(path.c_str());
  const int err = errno;
  ::close(fd);
  if (rc != 0 && err != ENOENT)
    return Status::IOError(path + ": remove: " + storage_internal::ErrnoText(err));
  return true;
}

Status CheckOneHistory(const std::string& folder, const std::vector<uint64_t>& revisions,
                       uint64_t held_revision, uint64_t held_history) {
  for (uint64_t r : revisions) {
    if (r == held_revision) continue;
    auto m = ReadRevisionFile(folder, r);
    if (!m.ok()) {
      if (m.status().code() == Status::Code::kNotFound) continue;
      return m.status();
    }
    if (m->history != held_history)
      return Status::Corruption(ChangesFile(folder, RevisionFileName(held_revision)) + " and " +
                                ChangesFile(folder, RevisionFileName(r)) +
                                ": revision files of different stores (one was copied in from another)");
  }
  return Status::Ok();
}

Result<bool> StoreFileIsAKeptBase(const std::string& store_path, const std::string& folder,
                                  const std::vector<uint64_t>& revisions) {
  MKTREE_ASSIGN_OR_RETURN(const RevisionFile store, FingerprintFile(store_path));
  std::vector<std::pair<uint64_t, std::string>> bases;  // of the revisions read
  for (auto it = revisions.rbegin(); it != revisions.rend(); ++it) {
    auto m = ReadRevisionFile(folder, *it);
    if (!m.ok()) {
      if (m.status().code() == Status::Code::kNotFound) continue;  // retired meanwhile
      return m.status();
    }
    if (m->base.store.bytes == store.bytes && m->base.store.fingerprint == store.fingerprint) return true;
    bases.push_back({*it, m->base.store.name});
  }
  // No match: a store built anew (another file), or this store's own base damaged (the same file: the
  // store file is a hard link of a base). Taking damage for a rebuild would answer the base alone and let a
  // writer replace the folder: refuse.
  struct stat st_store;
  if (::stat(store_path.c_str(), &st_store) != 0) return false;
  for (const auto& [revision, name] : bases) {
    struct stat st_base;
    const std::string base = ChangesFile(folder, name);
    if (::stat(base.c_str(), &st_base) == 0 && st_base.st_dev == st_store.st_dev &&
        st_base.st_ino == st_store.st_ino)
      return Status::Corruption(store_path + ": damaged: it is the base of revision " +
                                std::to_string(revision) + " (" + base +
                                ") but no longer has the size and fingerprint it was committed with");
  }
  return false;
}

Result<StoreRevision> OpenStoreRevision(const std::string& store_path, std::optional<uint64_t> revision) {
  const std::string folder = ChangesFolder(store_path);
  StoreRevision out;
  MKTREE_ASSIGN_OR_RETURN(std::vector<uint64_t> revisions, ListRevisionNumbers(folder));
  bool changed = !revisions.empty();
  if (changed) {
    MKTREE_ASSIGN_OR_RETURN(changed, StoreFileIsAKeptBase(store_path, folder, revisions));
  }
  if (!changed) {
    if (revision && *revision != 0)
      return Status::NotFound(store_path + ": revision " + std::to_string(*revision) +
                              " is not kept (the store has taken no change: it has revision 0 only)");
    return out;
  }
  // The newest may be retired between the listing and the hold (a compaction's commit): list again.
  for (int attempt = 0;; ++attempt) {
    const uint64_t want = revision ? *revision : revisions.back();
    auto hold = RevisionHold::Open(folder, want);
    if (hold.ok()) {
      MKTREE_RETURN_IF_ERROR(CheckOneHistory(folder, revisions, want, (*hold)->manifest().history));
      out.hold = std::move(*hold);
      return out;
    }
    if (revision || hold.status().code() != Status::Code::kNotFound || attempt == 8) return hold.status();
    MKTREE_ASSIGN_OR_RETURN(revisions, ListRevisionNumbers(folder));
    if (revisions.empty()) return hold.status();
  }
}

}  // namespace mktree
