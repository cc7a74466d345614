#include "engine/ingest/object_encoder.h"

#include <cmath>
#include <condition_variable>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "engine/core/guarded.h"
#include "engine/geometry/mesh_edges.h"

namespace mktree {

namespace {

// Batches amortise the hand-off (one lock and wake-up per batch, not per object) yet stay small enough
// that a few in flight cost little RAM (a batch of typical objects is well under kBatchRawBytes).
constexpr size_t kBatchObjects = 512;
constexpr uint64_t kBatchRawBytes = 2 << 20;
// Meshes larger than this are freed after use rather than kept for the next object read into their slot,
// so that a few big objects do not leave every slot holding a big buffer.
constexpr size_t kKeepMeshBytes = 64 << 10;

struct Batch {
  std::vector<SceneObject> objects;  // slots reused across batches; objects[0, count) are live
  size_t count = 0;
  std::vector<uint8_t> entries;   // the entries, back to back
  std::vector<size_t> entry_end;  // entry i is entries[entry_end[i-1], entry_end[i])
  std::vector<Box3f> boxes;
  size_t error_at = std::numeric_limits<size_t>::max();  // the first object that failed, if any
  Status error;
  bool done = false;  // guarded by the pipeline's mutex when workers run
};

// Encodes objects[0, count) in order, stopping at the first failure.
void EncodeBatch(const EncoderOptions& options, Batch* b) {
  b->entries.clear();
  b->entry_end.clear();
  b->boxes.clear();
  b->error_at = std::numeric_limits<size_t>::max();
  for (size_t i = 0; i < b->count; ++i) {
    const SceneObject& obj = b->objects[i];
    if (options.copy_stored_entries && !obj.stored_entry.empty()) {
      auto copied = CopyObjectEntry(obj.stored_entry, obj.id, &b->entries);
      if (!copied.ok()) {
        b->error = Status::Corruption("object " + std::to_string(obj.id) + " ('" + obj.name.substr(0, 100) +
                                      "'): its stored entry: " + copied.status().message());
        b->error_at = i;
        return;
      }
      b->entry_end.push_back(b->entries.size());
      b->boxes.push_back(copied->box);
      continue;
    }
    uint8_t shape = 0;
    if (options.keep_stored_shape && (obj.stored_shape & kShapeKnown) &&
        obj.stored_shape <= (kShapeKnown | kShapeEvenEdges | kShapeClosed)) {
      shape = obj.stored_shape;
    } else {
      const EdgeCheck edges = CheckEdges(obj.mesh);
      shape = kShapeKnown | (edges.even ? kShapeEvenEdges : 0) | (edges.closed ? kShapeClosed : 0);
    }
    Box3f box;
    auto encoded = EncodeObjectEntry(obj, options.origin, options.codec, &b->entries, shape, &box);
    if (!encoded.ok()) {
      b->error = encoded.status();
      b->error_at = i;
      return;
    }
    b->entry_end.push_back(b->entries.size());
    b->boxes.push_back(box);
  }
}

}  // namespace

uint32_t EncoderThreads(uint32_t requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

namespace {

// Returns the batch's objects to the sink, in order, then readies the batch for reuse.
Status DrainBatch(Batch* b, const EncodedSink& sink) {
  for (size_t i = 0; i < b->count; ++i) {
    if (i == b->error_at) return b->error;
    const size_t begin = i == 0 ? 0 : b->entry_end[i - 1];
    const EncodedObject e{b->boxes[i],
                          std::span<const uint8_t>(b->entries.data() + begin, b->entry_end[i] - begin)};
    MKTREE_RETURN_IF_ERROR(sink(b->objects[i], e));
    Mesh& m = b->objects[i].mesh;
    if (8 * m.vertices.capacity() + 4 * m.triangles.capacity() > kKeepMeshBytes) m = Mesh{};
    std::vector<uint8_t>& stored = b->objects[i].stored_entry;
    if (stored.capacity() > kKeepMeshBytes) stored = {};
  }
  if (b->entries.capacity() > 2 * kBatchRawBytes) b->entries = {};
  b->count = 0;
  return Status::Ok();
}

// Fills `b` with up to a batch of objects; false once the input is done (at its end or at a read error,
// kept in *read_error).
bool FillBatch(const ObjectReader& read, Batch* b, Status* read_error) {
  uint64_t raw = 0;
  while (b->count < kBatchObjects && raw < kBatchRawBytes) {
    if (b->objects.size() == b->count) b->objects.emplace_back();
    auto more = read(&b->objects[b->count]);
    if (!more.ok() || !*more) {
      // A read error surfaces after the objects before it, as in a sequential loop.
      if (!more.ok()) *read_error = more.status();
      return false;
    }
    raw += b->objects[b->count].mesh.RawGeometryBytes() + b->objects[b->count].stored_entry.size();
    ++b->count;
  }
  return true;
}

// The three stages on their own threads: the calling thread reads (for OBJ input it also assembles the
// parsed chunks, serial work that must not wait for encoding), `workers` threads encode, and one drain
// thread hands the batches to the sink in input order (spill writes: system calls and page faults).
// Batches circulate through a fixed pool, so the reader waits when encoding or the sink fall behind.
class Pipeline {
 public:
  Pipeline(const EncoderOptions& options, const EncodedSink& sink, uint32_t workers, size_t batches)
      : options_(options), sink_(sink) {
    for (size_t i = 0; i < batches; ++i) {
      all_.push_back(std::make_unique<Batch>());
      free_.push_back(all_.back().get());
    }
    try {
      for (uint32_t i = 0; i < workers; ++i) threads_.emplace_back([this] { Encode(); });
      drain_ = std::thread([this] { Drain(); });
    } catch (...) {  // a thread that cannot start: stop those that did
      static_cast<void>(Finish());
      throw;
    }
  }
  ~Pipeline() { static_cast<void>(Finish()); }  // on an early exit (an exception); its error is moot

  // A batch to fill, or nullptr when the drain stopped at an error.
  Batch* Take() {
    std::unique_lock<std::mutex> lock(mu_);
    free_cv_.wait(lock, [this] { return failed_ || !free_.empty(); });
    if (failed_) return nullptr;
    Batch* b = free_.back();
    free_.pop_back();
    return b;
  }
  // Queues a filled batch for encoding and, after the ones before it, for the sink.
  void Submit(Batch* b) {
    {
      std::lock_guard<std::mutex> g(mu_);
      b->done = false;
      pending_.push_back(b);
      ordered_.push_back(b);
    }
    work_cv_.notify_one();
    done_cv_.notify_all();
  }
  void Return(Batch* b) {
    std::lock_guard<std::mutex> g(mu_);
    free_.push_back(b);
  }
  // Ends the input, waits until every submitted batch is drained (or the drain failed) and joins the
  // threads. Returns the drain's error, if any.
  Status Finish() {
    {
      std::lock_guard<std::mutex> g(mu_);
      if (finished_) return drain_error_;
      finished_ = input_done_ = true;
    }
    done_cv_.notify_all();
    if (drain_.joinable()) drain_.join();
    {
      std::lock_guard<std::mutex> g(mu_);
      stop_ = true;
    }
    work_cv_.notify_all();
    for (std::thread& t : threads_) t.join();
    threads_.clear();
    return drain_error_;
  }

 private:
  void Encode() {
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      work_cv_.wait(lock, [this] { return stop_ || !pending_.empty(); });
      if (stop_) return;
      Batch* b = pending_.front();
      pending_.pop_front();
      lock.unlock();
      // An exception (std::bad_alloc) becomes the batch's error, at its first object not yet encoded.
      Status st = Guarded("encoding objects", [&] {
        EncodeBatch(options_, b);
        return Status::Ok();
      });
      if (!st.ok() && b->entry_end.size() < b->error_at) {
        b->error_at = b->entry_end.size();
        b->error = std::move(st);
      }
      lock.lock();
      b->done = true;
      done_cv_.notify_all();
    }
  }

  void Drain() {
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      done_cv_.wait(lock, [this] {
        return (!ordered_.empty() && ordered_.front()->done) || (input_done_ && ordered_.empty());
      });
      if (ordered_.empty()) return;
      Batch* b = ordered_.front();
      ordered_.pop_front();
      lock.unlock();
      Status st = Guarded("writing objects", [&] { return DrainBatch(b, sink_); });
      lock.lock();
      if (!st.ok()) {
        drain_error_ = std::move(st);
        failed_ = true;
        // Later batches are not drained; the ones still encoding finish before the workers are joined.
        free_cv_.notify_all();
        return;
      }
      free_.push_back(b);
      free_cv_.notify_one();
    }
  }

  const EncoderOptions options_;
  const EncodedSink& sink_;
  std::vector<std::unique_ptr<Batch>> all_;  // outlives the threads (joined in Finish)
  std::mutex mu_;
  std::condition_variable work_cv_, done_cv_, free_cv_;
  std::vector<Batch*> free_;
  std::deque<Batch*> pending_;  // to encode
  std::deque<Batch*> ordered_;  // submitted, not drained, in input order
  bool input_done_ = false, stop_ = false, failed_ = false, finished_ = false;
  Status drain_error_;
  std::vector<std::thread> threads_;  // the encoders
  std::thread drain_;
};

}  // namespace

Status EncodeObjects(const EncoderOptions& options, const ObjectReader& read, const EncodedSink& sink) {
  const uint32_t threads = EncoderThreads(options.threads);
  Status read_error;
  if (threads == 1) {  // everything on the calling thread
    Batch b;
    for (bool more = true; more;) {
      more = FillBatch(read, &b, &read_error);
      EncodeBatch(options, &b);
      MKTREE_RETURN_IF_ERROR(DrainBatch(&b, sink));
    }
    return read_error;
  }
  // One encoder per core: the reader and the drain mostly wait on each other and on the encoders, and
  // the kernel gives their cores to whichever stage has work. One batch filling, one per encoder, one
  // draining and two in between: with only one batch of slack (the earlier design), every stage was at
  // times blocked on another and a core idled. A batch holds at most ~kBatchRawBytes of geometry.
  Pipeline pipeline(options, sink, threads, threads + 4);
  for (bool more = true; more;) {
    Batch* b = pipeline.Take();
    if (b == nullptr) break;  // the drain failed: its error is the first in input order
    more = FillBatch(read, b, &read_error);
    if (b->count == 0) {
      pipeline.Return(b);
    } else {
      pipeline.Submit(b);
    }
  }
  MKTREE_RETURN_IF_ERROR(pipeline.Finish());
  return read_error;
}

}  // namespace mktree
