#include "engine/clash/clash_window.h"

#include <algorithm>
#include <utility>

#include "engine/clash/pair_rules.h"

namespace mktree::clash {

namespace {

// The heap a decoded leaf holds (about).
uint64_t DecodedLeafBytes(const LoadedLeaf& l) {
  uint64_t bytes = l.objects.capacity() * sizeof(LoadedObject);
  for (const LoadedObject& obj : l.objects) {
    if (obj.mesh)
      bytes += sizeof(Mesh) + obj.mesh->vertices.capacity() * sizeof(double) +
               obj.mesh->triangles.capacity() * sizeof(uint32_t);
    if (obj.shape) bytes += obj.shape->MemoryBytes();
  }
  return bytes;
}

}  // namespace

uint64_t WindowBudget(const ClashOptions& o, const PartNumbering& parts) {
  return o.window_bytes ? o.window_bytes
                        : std::max<uint64_t>(kDefaultClashWindowBytes,
                                             kDecodedBytesPerPayloadByte * parts.cache_bytes());
}

ClashWindow::ClashWindow(const PartNumbering& parts, const std::vector<NeededObjects>& needed,
                         const ClashFocus* focus)
    : parts_(parts), needed_(needed), focus_(focus), window_(parts.leaf_count()) {}

Status ClashWindow::Read(const std::vector<uint32_t>& leaves, WorkPool& pool, ClashStats* s) {
  if (pinned_.size() < leaves.size()) pinned_.resize(leaves.size());
  loaded_.clear();
  tasks_.clear();
  for (size_t i = 0; i < leaves.size(); ++i) {
    const uint32_t k = parts_.part_of(leaves[i]);
    const uint32_t leaf = leaves[i] - parts_.leaf_base(k);
    MKTREE_RETURN_IF_ERROR(ReadPinned(parts_.store(k), leaf, &io_, &seen_, &pinned_[i], parts_.page_base(k)));
    auto l = std::make_unique<LoadedLeaf>();
    const auto& entries = pinned_[i].view.entries();
    l->objects.resize(entries.size());
    for (uint32_t pos = 0; pos < entries.size(); ++pos) {
      LoadedObject& obj = l->objects[pos];
      obj.id = parts_.global_id(k, entries[pos].id);
      if (parts_.hidden(k, entries[pos].id)) {
        obj.box = Box3d();  // empty (min +inf, max -inf): GrownMeet never accepts it
        continue;
      }
      obj.box = ToBox3d(entries[pos].box);
      obj.in_focus = !focus_ || focus_->Holds(obj.id);
      obj.in_partner = !focus_ || focus_->HoldsPartner(obj.id);
      if (needed_[k](parts_.tree(k), leaf, pos)) tasks_.push_back({i, pos});
    }
    loaded_.push_back(std::move(l));
  }
  errors_.assign(tasks_.size(), Status::Ok());
  pool.For(tasks_.size(), [&](size_t k) {
    const DecodeTask& task = tasks_[k];
    const ObjectEntryView& e = pinned_[task.load].view.entry(task.pos);
    LoadedObject& obj = loaded_[task.load]->objects[task.pos];
    obj.resolution = CoordinateResolution(e.box);
    obj.mesh = std::make_unique<Mesh>();
    errors_[k] = DecodeMesh(parts_.store(parts_.part_of(leaves[task.load])), e, obj.mesh.get());
    if (errors_[k].ok()) obj.shape = std::make_unique<ClashShape>(*obj.mesh, StoredEdges(e));
  });
  for (size_t i = 0; i < leaves.size(); ++i) pinned_[i].Release();
  MKTREE_RETURN_IF_ERROR(FirstError(errors_));
  s->shapes_prepared += tasks_.size();
  for (size_t i = 0; i < leaves.size(); ++i) {
    loaded_[i]->bytes = DecodedLeafBytes(*loaded_[i]);
    bytes_ += loaded_[i]->bytes;
    window_[leaves[i]] = std::move(loaded_[i]);
  }
  s->window_peak_bytes = std::max(s->window_peak_bytes, bytes_);
  return Status::Ok();
}

void ClashWindow::Recount(std::span<const LeafPair> pairs, ClashStats* s) {
  for (const LeafPair& pair : pairs)
    for (uint32_t leaf : {pair.p, pair.q}) {
      LoadedLeaf& l = *window_[leaf];
      const uint64_t now = DecodedLeafBytes(l);
      bytes_ += now - l.bytes;
      l.bytes = now;
    }
  s->window_peak_bytes = std::max(s->window_peak_bytes, bytes_);
}

void ClashWindow::Drop(const std::vector<uint32_t>& leaves) {
  for (uint32_t leaf : leaves) {
    if (window_[leaf]) bytes_ -= window_[leaf]->bytes;
    window_[leaf].reset();
  }
}

}  // namespace mktree::clash
