#include "engine/ingest/read_and_spill.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <limits>

#include "engine/ingest/object_encoder.h"
#include "engine/ingest/scene_inputs.h"
#include "engine/store_format/record_codec.h"

namespace mktree {

namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

constexpr uint64_t kProgressEvery = 1 << 15;

// Boxes rounded by more than this fraction of their object's size draw a warning.
constexpr double kBoxRoundingWarnFraction = 1.0 / 16;

// Objects whose float32 box in the store frame is coarse against their size: counted, and the worst kept.
struct CoarseBoxes {
  uint64_t count = 0;
  double worst_ratio = 0;
  ObjectId worst_id = 0;
  std::string worst_name;
  double worst_size = 0, worst_rounding = 0;

  void Check(const SceneObject& obj, const Box3f& box) {
    double size = 0, far = 0;
    for (int i = 0; i < 3; ++i) {
      size = std::max(size, static_cast<double>(box.max[i]) - box.min[i]);
      far = std::max({far, std::fabs(double{box.min[i]}), std::fabs(double{box.max[i]})});
    }
    const double rounding = far * 0x1p-23;  // float32's spacing near `far`, within a factor of 2
    if (rounding <= kBoxRoundingWarnFraction * size) return;
    ++count;
    const double ratio = size > 0 ? rounding / size : std::numeric_limits<double>::infinity();
    if (count == 1 || ratio > worst_ratio) {
      worst_ratio = ratio;
      worst_id = obj.id;
      worst_name = obj.name;
      worst_size = size;
      worst_rounding = rounding;
    }
  }
  std::string Warning(const Vec3d& origin) const {
    std::string name = worst_name.substr(0, 100);
    for (char& c : name)
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';  // one line, whatever the name holds
    char buf[512];
    std::snprintf(
        buf, sizeof buf,
        "%llu objects lie so far from the store's origin (%.17g, %.17g, %.17g) that their float32 boxes "
        "are rounded by more than 1/16 of their size (worst: object %u '%.100s', size %.3g, rounding "
        "%.3g): AABB-mode answers and routing treat them as that much larger; exact answers are not "
        "affected",
        static_cast<unsigned long long>(count), origin.x, origin.y, origin.z, worst_id, name.c_str(),
        worst_size, worst_rounding);
    return buf;
  }
};

// The objects of every input in order (SceneInputs), reporting progress on the calling thread and
// handing each finished input's warnings to the build's as it finishes.
class SceneReader {
 public:
  SceneReader(const std::vector<SceneOpener>& inputs, const IngestOptions& options,
              std::vector<std::string>* warnings)
      : inputs_(inputs), options_(options), warnings_(warnings) {}

  // Fills *obj with the next object; false after the last input's last object.
  Result<bool> Next(SceneObject* obj) {
    Result<bool> more = inputs_.Next(obj);
    for (std::string& w : inputs_.TakeWarnings()) warnings_->push_back(std::move(w));
    if (!more.ok() || !*more) return more;
    // Reported here, on the calling thread, not by the sink (a drain thread): a progress callback may
    // need the caller's thread (Python checks Ctrl-C only on its main thread).
    if (inputs_.objects_read() % kProgressEvery == 0)
      ReportProgress(options_, IngestStage::kRead, inputs_.objects_read(), 0);
    return true;
  }
  ObjectId objects_read() const { return inputs_.objects_read(); }

 private:
  SceneInputs inputs_;
  const IngestOptions& options_;
  std::vector<std::string>* warnings_;
};

// The encoder's sink: spills each object's entry and record in id order and keeps its BuildObject.
// Called on one thread at a time (EncodeObjects).
class ObjectSpiller {
 public:
  ObjectSpiller(SpilledObjects* out, IngestReport* report)
      : out_(out), report_(report), source_index_(&out->sources) {}

  Status Spill(const SceneObject& obj, const EncodedObject& encoded) {
    coarse_.Check(obj, encoded.box);
    BuildObject rec;
    rec.id = obj.id;
    rec.box = encoded.box;
    rec.encoded_bytes = static_cast<uint32_t>(encoded.entry.size());
    // Entries go back to back in id order: their offsets are the prefix sums of the sizes.
    if (auto offset = out_->entries->Append(encoded.entry.data(), encoded.entry.size()); !offset.ok())
      return offset.status();
    // The object's record (box, source, name, attributes) as the store encodes it, spilled in id order.
    record_bytes_.clear();
    if (Status st =
            EncodeRecord(encoded.box, source_index_.Of(obj.source), obj.name, obj.attributes, &record_bytes_);
        !st.ok())
      return Status::InvalidArgument("object " + std::to_string(obj.id) + " '" + obj.name.substr(0, 100) +
                                     "': " + st.message());
    if (auto st = out_->records->Append(record_bytes_.data(), record_bytes_.size()); !st.ok())
      return st.status();
    out_->objects.push_back(rec);
    // From the entry's header, which a copied entry (IngestOptions::copy_stored_entries) has without a mesh:
    // its raw bytes are Mesh::RawGeometryBytes but the two counts.
    ObjectEntryView e;
    MKTREE_RETURN_IF_ERROR(ParseObjectEntry(encoded.entry.data(), encoded.entry.size(), &e));
    report_->triangles += e.triangle_count;
    report_->raw_geometry_bytes += 8 + uint64_t{e.raw_bytes};
    report_->encoded_bytes += rec.encoded_bytes;
    return Status::Ok();
  }
  const CoarseBoxes& coarse() const { return coarse_; }

 private:
  SpilledObjects* out_;
  IngestReport* report_;
  SourceIndex source_index_;
  std::vector<uint8_t> record_bytes_;
  CoarseBoxes coarse_;
};

// A dictionary's training sample: objects packed as the encoder will pack them, whole objects only, up to
// kDictionarySampleBytes. An object that cannot be packed ends it (the encoder reports it in order).
class DictionarySample {
 public:
  DictionarySample(const Vec3d& origin, const CodecOptions& codec) : origin_(origin), codec_(codec) {}
  // False when the sample is full (or `obj` cannot be packed): read no more for it.
  bool Add(const SceneObject& obj) {
    const size_t before = sample_.size();
    if (!PackObjectGeometry(obj, origin_, codec_.shuffle, &sample_).ok()) return false;
    if (sample_.size() > kDictionarySampleBytes) {
      sample_.resize(before);
      return false;
    }
    sizes_.push_back(sample_.size() - before);
    return true;
  }
  // Null when zstd trains none on it.
  Result<std::shared_ptr<const CodecDictionary>> Train() const {
    std::vector<uint8_t> dictionary = TrainDictionary(sample_, sizes_, codec_.zstd_level);
    if (dictionary.empty()) return std::shared_ptr<const CodecDictionary>();
    auto loaded = CodecDictionary::Load(std::move(dictionary), codec_.zstd_level);
    if (!loaded.ok())
      return Status::Internal("the dictionary just trained does not load: " + loaded.status().message());
    return std::shared_ptr<const CodecDictionary>(*loaded);
  }

 private:
  Vec3d origin_;
  const CodecOptions& codec_;
  std::vector<uint8_t> sample_;
  std::vector<size_t> sizes_;
};

// Trains the store's dictionary (object_codec.h) on `first` and the objects after it, read ahead into
// *ahead, and hands it to the encoder.
Status TrainStoreDictionary(const SceneObject& first, SceneReader* reader, std::deque<SceneObject>* ahead,
                            EncoderOptions* encoder, IngestReport* report) {
  const auto train_start = Clock::now();
  DictionarySample sample(encoder->origin, encoder->codec);
  for (bool more = sample.Add(first); more;) {
    SceneObject obj;
    auto got = reader->Next(&obj);
    if (!got.ok()) return got.status();
    if (!*got) break;
    ahead->push_back(std::move(obj));
    more = sample.Add(ahead->back());
  }
  MKTREE_ASSIGN_OR_RETURN(auto dictionary, sample.Train());
  if (dictionary) encoder->codec.dictionary = std::move(dictionary);
  report->dictionary_bytes = encoder->codec.dictionary ? encoder->codec.dictionary->bytes().size() : 0;
  report->dictionary_seconds = Seconds(train_start);
  return Status::Ok();
}

void TrimMalloc() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace

Result<std::shared_ptr<const CodecDictionary>> TrainBuildDictionary(const std::vector<SceneOpener>& inputs,
                                                                    const IngestOptions& options,
                                                                    const Vec3d& origin) {
  if (options.store.codec.codec != Codec::kZstd) return std::shared_ptr<const CodecDictionary>();
  std::vector<std::string> warnings;  // the build that reads the inputs again reports them
  IngestOptions quiet = options;
  quiet.progress = nullptr;  // the build's own reading reports progress
  SceneReader reader(inputs, quiet, &warnings);
  DictionarySample sample(origin, options.store.codec);
  for (;;) {
    SceneObject obj;
    MKTREE_ASSIGN_OR_RETURN(const bool more, reader.Next(&obj));
    if (!more || !sample.Add(obj)) break;
  }
  return sample.Train();
}

void RemoveStaleSpills(const std::string& dir, const std::string& stem) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    for (const char* kind : {".geometry-spill.", ".record-spill.", ".name-spill."}) {
      const std::string prefix = "." + stem + kind;
      if (name.size() == prefix.size() + 6 && name.compare(0, prefix.size(), prefix) == 0) {
        std::error_code rm;
        fs::remove(it->path(), rm);
      }
    }
  }
}

Result<ReadAndSpillOutput> ReadAndSpill(const std::vector<SceneOpener>& inputs, const IngestOptions& options,
                                        const SpillPlace& place, IngestReport* report) {
  ReadAndSpillOutput out;
  SpilledObjects& spilled = out.spilled;
  FileOps& ops = place.ops != nullptr ? *place.ops : DefaultFileOps();
  MKTREE_ASSIGN_OR_RETURN(spilled.entries,
                          SpillFile::Create(place.dir, "." + place.stem + ".geometry-spill", ops));
  MKTREE_ASSIGN_OR_RETURN(spilled.records,
                          SpillFile::Create(place.dir, "." + place.stem + ".record-spill", ops));

  SceneReader reader(inputs, options, &report->warnings);
  // The store frame, chosen from the first object before any is encoded (entries hold boxes in it).
  SceneObject first;
  MKTREE_ASSIGN_OR_RETURN(bool first_pending, reader.Next(&first));
  report->origin = options.origin  ? *options.origin
                   : first_pending ? ChooseStoreOrigin(first.mesh.Bounds())
                                   : Vec3d{};
  EncoderOptions encoder;
  encoder.codec = options.store.codec;
  encoder.codec.dictionary.reset();
  encoder.origin = report->origin;
  encoder.threads = options.threads;
  encoder.keep_stored_shape = options.keep_stored_shape;
  // The objects read ahead to train the dictionary, handed to the encoder after `first`.
  std::deque<SceneObject> ahead;
  // Copied entries are valid only in their own store's frame, under its dictionary.
  if (options.copy_stored_entries && !(options.origin && options.dictionary))
    return Status::Internal("a build that copies stored entries has no frame or dictionary given");
  encoder.copy_stored_entries = options.copy_stored_entries;
  if (options.dictionary) {
    encoder.codec.dictionary = *options.dictionary;
    if (encoder.codec.dictionary && !encoder.codec.dictionary->cdict() &&
        encoder.codec.codec == Codec::kZstd) {
      // A reader's dictionary only decompresses: the objects encoded here need it loaded to compress.
      MKTREE_ASSIGN_OR_RETURN(
          encoder.codec.dictionary,
          CodecDictionary::Load(encoder.codec.dictionary->bytes(), encoder.codec.zstd_level));
    }
    report->dictionary_bytes = encoder.codec.dictionary ? encoder.codec.dictionary->bytes().size() : 0;
  } else if (first_pending && encoder.codec.codec == Codec::kZstd) {
    MKTREE_RETURN_IF_ERROR(TrainStoreDictionary(first, &reader, &ahead, &encoder, report));
  }
  // Training's buffers (the sample, zstd's tables) are free: hand them back before encoding.
  TrimMalloc();
  out.dictionary = encoder.codec.dictionary;
  auto read_all = [&](SceneObject* obj) -> Result<bool> {
    if (first_pending) {
      std::swap(*obj, first);
      first_pending = false;
      return true;
    }
    if (ahead.empty()) return reader.Next(obj);
    std::swap(*obj, ahead.front());
    ahead.pop_front();
    return true;
  };
  if (options.expected_objects > 0) spilled.objects.reserve(options.expected_objects);
  ObjectSpiller spiller(&spilled, report);
  MKTREE_RETURN_IF_ERROR(
      EncodeObjects(encoder, read_all,
                    [&](const SceneObject& obj, const EncodedObject& e) { return spiller.Spill(obj, e); }));
  // The pipeline's threads freed their batches and buffers into their own malloc arenas, which keep the
  // pages; hand them back before the tree build, the build's memory peak.
  TrimMalloc();
  if (spiller.coarse().count > 0) report->warnings.push_back(spiller.coarse().Warning(report->origin));
  report->objects = reader.objects_read();
  ReportProgress(options, IngestStage::kRead, report->objects, report->objects);
  MKTREE_RETURN_IF_ERROR(spilled.entries->Flush());
  MKTREE_RETURN_IF_ERROR(spilled.records->Flush());
  return out;
}

}  // namespace mktree
