#include "engine/ingest/object_encoder.h"

#include <cmath>
#include <condition_variable>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "engine/geometry/mesh_edges.h"

namespace mktree {

namespace {

// Batches amortise the hand-off (one lock and wake-up per batch, not per object) yet stay small enough
// that a few in flight cost little RAM: the tanker's objects average ~660 bytes, so a batch is ~0.3 MiB.
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
    const EdgeCheck edges = CheckEdges(obj.mesh);
    const uint8_t shape =
        kShapeKnown | (edges.even ? kShapeEvenEdges : 0) | (edges.closed ? kShapeClosed : 0);
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

// Worker threads taking batches from a queue. The destructor stops and joins them (after their current
// batch), so an early return from EncodeObjects leaves no thread behind.
class WorkerPool {
 public:
  WorkerPool(const EncoderOptions& options, uint32_t workers) : options_(options) {
    for (uint32_t i = 0; i < workers; ++i) threads_.emplace_back([this] { Run(); });
  }
  ~WorkerPool() {
    {
      std::lock_guard<std::mutex> g(mu_);
      stop_ = true;
    }
    work_cv_.notify_all();
    for (std::thread& t : threads_) t.join();
  }

  void Submit(Batch* b) {
    if (threads_.empty()) {  // single-threaded: encode right here
      EncodeBatch(options_, b);
      b->done = true;
      return;
    }
    {
      std::lock_guard<std::mutex> g(mu_);
      b->done = false;
      pending_.push_back(b);
    }
    work_cv_.notify_one();
  }

  // Waits until `b` is encoded. Rather than idle, the caller encodes pending batches itself meanwhile.
  void Await(Batch* b) {
    std::unique_lock<std::mutex> lock(mu_);
    while (!b->done) {
      if (!pending_.empty()) {
        Batch* mine = pending_.front();
        pending_.pop_front();
        lock.unlock();
        EncodeBatch(options_, mine);
        lock.lock();
        mine->done = true;
        continue;
      }
      done_cv_.wait(lock);
    }
  }

  bool Done(Batch* b) {
    std::lock_guard<std::mutex> g(mu_);
    return b->done;
  }

 private:
  void Run() {
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      work_cv_.wait(lock, [this] { return stop_ || !pending_.empty(); });
      if (stop_) return;
      Batch* b = pending_.front();
      pending_.pop_front();
      lock.unlock();
      EncodeBatch(options_, b);
      lock.lock();
      b->done = true;
      done_cv_.notify_all();
    }
  }

  const EncoderOptions options_;
  std::mutex mu_;
  std::condition_variable work_cv_, done_cv_;
  std::deque<Batch*> pending_;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace

uint32_t EncoderThreads(uint32_t requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

Status EncodeObjects(const EncoderOptions& options, const ObjectReader& read, const EncodedSink& sink) {
  const uint32_t threads = EncoderThreads(options.threads);
  std::vector<std::unique_ptr<Batch>> all;  // declared before the pool: workers may use them until joined
  // The calling thread reads, drains and helps encode, so threads - 1 workers keep every core busy.
  WorkerPool pool(options, threads - 1);
  // Enough batches in flight that no worker waits for the reader, few enough to bound memory.
  const size_t max_in_flight = threads == 1 ? 1 : threads + 2;
  std::vector<Batch*> free_batches;
  std::deque<Batch*> in_flight;  // in input order
  Status read_error;
  bool input_done = false;

  // Hands the oldest batch's objects to the sink, in order; then recycles the batch.
  auto drain = [&](Batch* b) -> Status {
    for (size_t i = 0; i < b->count; ++i) {
      if (i == b->error_at) return b->error;
      const size_t begin = i == 0 ? 0 : b->entry_end[i - 1];
      const EncodedObject e{b->boxes[i],
                            std::span<const uint8_t>(b->entries.data() + begin, b->entry_end[i] - begin)};
      MKTREE_RETURN_IF_ERROR(sink(b->objects[i], e));
      Mesh& m = b->objects[i].mesh;
      if (8 * m.vertices.capacity() + 4 * m.triangles.capacity() > kKeepMeshBytes) m = Mesh{};
    }
    if (b->entries.capacity() > 2 * kBatchRawBytes) b->entries = {};
    b->count = 0;
    free_batches.push_back(b);
    return Status::Ok();
  };

  for (;;) {
    // Drain what is finished first: it frees batches and keeps the spill writes flowing.
    while (!in_flight.empty() && pool.Done(in_flight.front())) {
      Batch* b = in_flight.front();
      in_flight.pop_front();
      MKTREE_RETURN_IF_ERROR(drain(b));
    }
    if (!input_done && in_flight.size() < max_in_flight) {
      if (free_batches.empty()) {
        all.push_back(std::make_unique<Batch>());
        free_batches.push_back(all.back().get());
      }
      Batch* b = free_batches.back();
      free_batches.pop_back();
      uint64_t raw = 0;
      while (b->count < kBatchObjects && raw < kBatchRawBytes) {
        if (b->objects.size() == b->count) b->objects.emplace_back();
        auto more = read(&b->objects[b->count]);
        if (!more.ok() || !*more) {
          // A read error surfaces after the objects before it, as in a sequential loop.
          if (!more.ok()) read_error = more.status();
          input_done = true;
          break;
        }
        raw += b->objects[b->count].mesh.RawGeometryBytes();
        ++b->count;
      }
      if (b->count == 0) {
        free_batches.push_back(b);
      } else {
        pool.Submit(b);
        in_flight.push_back(b);
      }
      continue;
    }
    if (in_flight.empty()) break;
    Batch* b = in_flight.front();
    pool.Await(b);
    in_flight.pop_front();
    MKTREE_RETURN_IF_ERROR(drain(b));
  }
  return read_error;
}

}  // namespace mktree
