#include "bench/change_workload.h"

#include <algorithm>
#include <memory>
#include <random>

#include "engine/generator/tanker_generator.h"

namespace mktree::bench {
namespace {

Box3d Moved(const Box3d& b, const Vec3d& offset) {
  Box3d r;
  for (int i = 0; i < 3; ++i) {
    r.min[i] = b.min[i] + offset[i];
    r.max[i] = b.max[i] + offset[i];
  }
  return r;
}

// Builds the script while keeping the live set: ids live, in no order (picked at random by position).
class ScriptWriter {
 public:
  ScriptWriter(ChangeWorkload* w, std::vector<Box3d> bounds)
      : w_(w), bounds_(std::move(bounds)), rng_(w->change_seed * 0x9E3779B97F4A7C15ull + 12345) {
    live_ids_.resize(w->objects);
    for (uint64_t i = 0; i < w->objects; ++i) live_ids_[i] = static_cast<ObjectId>(i);
    next_id_ = w->objects;
  }

  Result<ChangeBatchScript> Batch(uint64_t size, uint64_t rotation) {
    uint64_t count[3];
    for (uint64_t kind = 0; kind < 3; ++kind)
      count[kind] = size / 3 + ((kind + 3 - rotation % 3) % 3 < size % 3);
    const uint64_t adds = count[0], removes = count[1], replaces = count[2];
    const size_t live = live_ids_.size();
    if (removes + replaces > live)
      return Status::InvalidArgument("changes_bench: a batch of " + std::to_string(size) + " needs " +
                                     std::to_string(removes + replaces) + " live objects, " +
                                     std::to_string(live) + " are left");
    // Partial Fisher-Yates: the picked ids end up at the tail, replaces first, then removes.
    const size_t picked = removes + replaces;
    for (size_t j = 0; j < picked; ++j) {
      std::uniform_int_distribution<size_t> pick(0, live - 1 - j);
      std::swap(live_ids_[pick(rng_)], live_ids_[live - 1 - j]);
    }
    ChangeBatchScript batch;
    batch.changes.reserve(size);
    for (uint64_t i = 0; i < adds; ++i) {
      Change c = Copy(ChangeKind::kAdd, static_cast<ObjectId>(next_id_++));
      w_->live.push_back(1);
      w_->boxes.push_back(c.box);
      w_->origins.push_back({c.source, c.offset, true});
      batch.changes.push_back(c);
    }
    for (size_t j = live - removes; j < live; ++j) {
      Change c;
      c.kind = ChangeKind::kRemove;
      c.id = live_ids_[j];
      c.old_box = w_->boxes[c.id];
      w_->live[c.id] = 0;
      batch.changes.push_back(c);
    }
    for (size_t j = live - picked; j < live - removes; ++j) {
      Change c = Copy(ChangeKind::kReplace, live_ids_[j]);
      c.old_box = w_->boxes[c.id];
      w_->boxes[c.id] = c.box;
      w_->origins[c.id] = {c.source, c.offset, true};
      batch.changes.push_back(c);
    }
    live_ids_.resize(live - removes);
    for (const Change& c : batch.changes)
      if (c.kind == ChangeKind::kAdd) live_ids_.push_back(c.id);
    return batch;
  }

 private:
  // A copy of a random tanker object, moved so that its box stays inside the scene's box.
  Change Copy(ChangeKind kind, ObjectId id) {
    std::uniform_int_distribution<ObjectId> source(0, static_cast<ObjectId>(w_->objects - 1));
    std::uniform_real_distribution<double> u(0, 1);
    Change c;
    c.kind = kind;
    c.id = id;
    c.source = source(rng_);
    const Box3d& b = bounds_[c.source];
    for (int i = 0; i < 3; ++i) {
      const double lo = w_->scene_bounds.min[i] - b.min[i], hi = w_->scene_bounds.max[i] - b.max[i];
      c.offset[i] = lo + u(rng_) * (hi - lo);
    }
    c.box = RoundOutward(Moved(b, c.offset));
    return c;
  }

  ChangeWorkload* w_;
  std::vector<Box3d> bounds_;  // of the tanker's objects, by id
  std::mt19937_64 rng_;
  std::vector<ObjectId> live_ids_;
  uint64_t next_id_ = 0;
};

}  // namespace

uint64_t ChangeWorkload::live_count() const {
  return static_cast<uint64_t>(std::count(live.begin(), live.end(), uint8_t{1}));
}

Result<ChangeWorkload> MakeChangeWorkload(uint64_t objects, uint64_t seed, uint64_t change_seed,
                                          const std::vector<uint64_t>& sizes,
                                          const std::vector<uint64_t>& batches) {
  if (objects == 0) return Status::InvalidArgument("changes_bench: the tanker needs at least one object");
  if (sizes.size() != batches.size())
    return Status::InvalidArgument("changes_bench: " + std::to_string(sizes.size()) + " batch sizes but " +
                                   std::to_string(batches.size()) + " batch counts");
  ChangeWorkload w;
  w.objects = objects;
  w.seed = seed;
  w.change_seed = change_seed;
  std::vector<Box3d> bounds;
  bounds.reserve(objects);
  w.base_boxes.reserve(objects);
  std::unique_ptr<SceneSource> source = MakeTankerSource(objects, seed);
  SceneObject o;
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, source->Next(&o));
    if (!more) break;
    const Box3d b = o.mesh.Bounds();
    w.scene_bounds.Extend(b.min[0], b.min[1], b.min[2]);
    w.scene_bounds.Extend(b.max[0], b.max[1], b.max[2]);
    bounds.push_back(b);
    w.base_boxes.push_back(RoundOutward(b));
  }
  w.boxes = w.base_boxes;
  w.live.assign(objects, 1);
  w.origins.resize(objects);
  for (uint64_t i = 0; i < objects; ++i) w.origins[i].source = static_cast<ObjectId>(i);
  ScriptWriter writer(&w, std::move(bounds));
  for (size_t g = 0; g < sizes.size(); ++g) {
    BatchGroup group;
    group.size = sizes[g];
    for (uint64_t b = 0; b < batches[g]; ++b) {
      MKTREE_ASSIGN_OR_RETURN(ChangeBatchScript batch, writer.Batch(sizes[g], b));
      group.batches.push_back(std::move(batch));
    }
    w.groups.push_back(std::move(group));
  }
  return w;
}

Result<SourceObjects> LoadSourceObjects(const ChangeWorkload& workload) {
  std::vector<uint8_t> wanted(workload.objects, 0);
  for (const BatchGroup& g : workload.groups)
    for (const ChangeBatchScript& b : g.batches)
      for (const Change& c : b.changes)
        if (c.kind != ChangeKind::kRemove) wanted[c.source] = 1;
  SourceObjects sources;
  std::unique_ptr<SceneSource> source = MakeTankerSource(workload.objects, workload.seed);
  SceneObject o;
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, source->Next(&o));
    if (!more) break;
    if (wanted[o.id]) sources.emplace(o.id, o);
  }
  return sources;
}

SceneObject MovedCopy(const SceneObject& source, const Vec3d& offset, ObjectId id) {
  SceneObject copy = source;
  copy.id = id;
  copy.name += "+moved";
  for (size_t v = 0; v < copy.mesh.vertices.size(); v += 3)
    for (int i = 0; i < 3; ++i) copy.mesh.vertices[v + i] += offset[i];
  return copy;
}

ObjectSource LiveSetSource(const ChangeWorkload& workload, const SourceObjects& sources) {
  struct State {
    std::unique_ptr<SceneSource> tanker;
    uint64_t next = 0;  // the next id to consider
  };
  auto state = std::make_shared<State>();
  state->tanker = MakeTankerSource(workload.objects, workload.seed);
  return [&workload, &sources, state](SceneObject* out) -> Result<bool> {
    while (state->next < workload.live.size()) {
      const uint64_t id = state->next++;
      if (id < workload.objects) {
        MKTREE_ASSIGN_OR_RETURN(const bool more, state->tanker->Next(out));
        if (!more)
          return Status::Internal("changes_bench: the tanker ended before object " + std::to_string(id));
      }
      if (!workload.live[id]) continue;
      const GeometryOrigin& origin = workload.origins[id];
      if (origin.moved) *out = MovedCopy(sources.at(origin.source), origin.offset, static_cast<ObjectId>(id));
      return true;
    }
    return false;
  };
}

BuildOptions ChangesBenchBuildOptions() {
  BuildOptions o;
  o.backend = BuildOptions::Backend::kPagedFile;
  o.codec = BuildOptions::Codec::kZstd;
  o.block_size = 4096;
  o.blocks_per_page = 3;
  return o;
}

}  // namespace mktree::bench
