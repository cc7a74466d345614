// The Python module `mktree` (docs/python.md): the public API of include/mktree/ (database.h, build.h,
// changes.h, clash.h, clash_tests.h) with numpy arrays in and out. Queries, builds, commits and compactions
// run with the GIL released; the callbacks into Python (the objects of a build, its progress) take it back. A
// non-ok Status raises mktree.Error with Status::ToString() as its message; a Python exception raised in a
// callback ends the build and is raised again as it was.
#include <mktree/build.h>
#include <mktree/changes.h>
#include <mktree/clash_tests.h>
#include <mktree/database.h>
#include <mktree/version.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace py = pybind11;

namespace mktree {
namespace {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] void Raise(const Status& st) { throw Error(st.ToString()); }

template <typename T>
T Take(Result<T> r) {
  if (!r.ok()) Raise(r.status());
  return std::move(r).value();
}

// Names and attributes are any bytes: decoded as UTF-8, undecodable bytes kept as surrogates (as the os
// module does for file names), so that nothing is lost.
py::str Text(const std::string& s) {
  return py::reinterpret_steal<py::str>(PyUnicode_DecodeUTF8(s.data(), s.size(), "surrogateescape"));
}

std::string Bytes(py::handle h) {
  if (py::isinstance<py::bytes>(h)) return h.cast<std::string>();
  py::object s = py::str(h);
  PyObject* b = PyUnicode_AsEncodedString(s.ptr(), "utf-8", "surrogateescape");
  if (b == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::bytes>(b).cast<std::string>();
}

std::string PathText(py::handle path) { return Bytes(py::module_::import("os").attr("fspath")(path)); }

py::array_t<uint32_t> IdArray(const uint32_t* ids, size_t n) {
  py::array_t<uint32_t> a(static_cast<py::ssize_t>(n));
  if (n != 0) std::memcpy(a.mutable_data(), ids, n * sizeof(uint32_t));
  return a;
}

py::dict StatsDict(const QueryStats& s, bool truncated) {
  py::dict d;
  d["hits"] = s.hits;
  d["truncated"] = truncated;
  d["pages_read"] = s.pages_read;
  d["pages_touched"] = s.pages_touched;
  d["cache_hits"] = s.cache_hits;
  d["bytes_read"] = s.bytes_read;
  d["leaves_visited"] = s.leaves_visited;
  d["leaves_filtered"] = s.leaves_filtered;
  d["leaves_with_hits"] = s.leaves_with_hits;
  d["internal_nodes_visited"] = s.internal_nodes_visited;
  d["split_nodes_visited"] = s.split_nodes_visited;
  d["candidates_tested"] = s.candidates_tested;
  return d;
}

QueryMode Mode(bool exact) { return exact ? QueryMode::kExact : QueryMode::kAabb; }

Vec3d ToVec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }

// A point query when `max` is None, else a box query.
Query MakeQuery(const std::array<double, 3>& min, const std::optional<std::array<double, 3>>& max,
                bool exact) {
  if (!max) return Query::Point(ToVec(min), Mode(exact));
  Box3d box;
  box.min = min;
  box.max = *max;
  return Query::Box(box, Mode(exact));
}

py::object RunOne(const Database& db, Query q, std::optional<uint64_t> limit, bool stats) {
  if (limit) q.limit = *limit;
  QueryResult r;
  Status st;
  {
    py::gil_scoped_release nogil;
    st = db.Run(q, &r);
  }
  if (!st.ok()) Raise(st);
  py::array_t<uint32_t> ids = IdArray(r.hits.data(), r.hits.size());
  if (!stats) return ids;
  return py::make_tuple(ids, StatsDict(r.stats, r.truncated));
}

// Many queries, one a row of `rows` ([n, 3] points or [n, 6] boxes: min x, y, z, max x, y, z), on
// `threads` threads. Returns a list of sorted uint32 arrays, or with csr the pair (offsets int64 [n + 1],
// ids uint32): the answer of row i is ids[offsets[i]:offsets[i + 1]].
py::object RunMany(const Database& db, const py::handle& rows_in, int width, bool exact, unsigned threads,
                   bool csr, std::optional<uint64_t> limit) {
  auto rows = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(rows_in);
  if (!rows || rows.ndim() != 2 || rows.shape(1) != width)
    throw py::value_error("expected an array of shape (n, " + std::to_string(width) + ")");
  const size_t n = static_cast<size_t>(rows.shape(0));
  std::vector<Query> queries(n);
  const double* p = rows.data();
  for (size_t i = 0; i < n; ++i, p += width) {
    if (width == 3) {
      queries[i] = Query::Point({p[0], p[1], p[2]}, Mode(exact));
    } else {
      Box3d box;
      box.min = {p[0], p[1], p[2]};
      box.max = {p[3], p[4], p[5]};
      queries[i] = Query::Box(box, Mode(exact));
    }
    if (limit) queries[i].limit = *limit;
  }
  std::vector<int64_t> offsets{0};
  offsets.reserve(n + 1);
  std::vector<uint32_t> ids;
  Status st;
  {
    py::gil_scoped_release nogil;
    BatchOptions options;
    options.threads = threads;
    st = db.RunBatchStreamed(queries, options, [&](uint64_t, const QueryResult& r) {
      ids.insert(ids.end(), r.hits.begin(), r.hits.end());
      offsets.push_back(static_cast<int64_t>(ids.size()));
      return Status::Ok();
    });
  }
  if (!st.ok()) Raise(st);
  if (csr) {
    py::array_t<int64_t> off(static_cast<py::ssize_t>(offsets.size()));
    std::memcpy(off.mutable_data(), offsets.data(), offsets.size() * sizeof(int64_t));
    return py::make_tuple(off, IdArray(ids.data(), ids.size()));
  }
  py::list out(n);
  for (size_t i = 0; i < n; ++i)
    out[i] = IdArray(ids.data() + offsets[i], static_cast<size_t>(offsets[i + 1] - offsets[i]));
  return out;
}

// `st` with `prefix` before its message, its code kept.
Status Prefix(const Status& st, const std::string& prefix) {
  std::string m = prefix + st.message();
  switch (st.code()) {
    case Status::Code::kOk:
      return st;
    case Status::Code::kInvalidArgument:
      return Status::InvalidArgument(std::move(m));
    case Status::Code::kNotFound:
      return Status::NotFound(std::move(m));
    case Status::Code::kCorruption:
      return Status::Corruption(std::move(m));
    case Status::Code::kIOError:
      return Status::IOError(std::move(m));
    case Status::Code::kUnsupported:
      return Status::Unsupported(std::move(m));
    case Status::Code::kInternal:
      break;
  }
  return Status::Internal(std::move(m));
}

// Runs job(0..count-1) on `threads` threads (0: one per core), the GIL released by the caller; returns the
// error of the lowest failing index, the jobs after a failure may be skipped.
Status ParallelFor(size_t count, unsigned threads, const std::function<Status(size_t)>& job) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  threads = static_cast<unsigned>(std::min<size_t>(threads, std::max<size_t>(count, 1)));
  std::atomic<size_t> next{0};
  std::atomic<size_t> failed{count};
  std::vector<Status> errors(threads, Status::Ok());
  std::vector<size_t> error_at(threads, count);
  auto work = [&](unsigned w) {
    for (size_t i; (i = next.fetch_add(1)) < count && i < failed.load();) {
      Status st = job(i);
      if (st.ok()) continue;
      if (i < error_at[w]) errors[w] = std::move(st), error_at[w] = i;
      size_t f = failed.load();
      while (i < f && !failed.compare_exchange_weak(f, i)) {
      }
    }
  };
  std::vector<std::thread> pool;
  for (unsigned w = 1; w < threads; ++w) pool.emplace_back(work, w);
  work(0);
  for (std::thread& t : pool) t.join();
  size_t best = 0;
  for (unsigned w = 1; w < threads; ++w)
    if (error_at[w] < error_at[best]) best = w;
  return error_at[best] < count ? Prefix(errors[best], "query " + std::to_string(error_at[best]) + ": ")
                                : Status::Ok();
}

// An (n, width) float64 array, or a value error naming `what`.
py::array_t<double, py::array::c_style | py::array::forcecast> Rows(const py::handle& in, int width,
                                                                    const char* what) {
  auto rows = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(in);
  if (!rows || rows.ndim() != 2 || rows.shape(1) != width)
    throw py::value_error(std::string(what) + ": expected an array of shape (n, " + std::to_string(width) +
                          ")");
  return rows;
}

// The k nearest objects of each row of `points` ((n, 3)): (ids int64 (n, k), -1 past the answer;
// distances float64 (n, k), inf past it; points float64 (n, k, 3), nan past it).
py::tuple NearestMany(const Database& db, const py::handle& points_in, uint64_t k, double max_distance,
                      unsigned threads) {
  if (k == 0 || k > (uint64_t{1} << 20)) throw py::value_error("k must be from 1 to 2^20");
  auto points = Rows(points_in, 3, "points");
  const size_t n = static_cast<size_t>(points.shape(0));
  const py::ssize_t sn = static_cast<py::ssize_t>(n), sk = static_cast<py::ssize_t>(k);
  py::array_t<int64_t> ids({sn, sk});
  py::array_t<double> dist({sn, sk});
  py::array_t<double> at({sn, sk, py::ssize_t{3}});
  int64_t* id_out = ids.mutable_data();
  double* d_out = dist.mutable_data();
  double* p_out = at.mutable_data();
  const double* p = points.data();
  Status st;
  {
    py::gil_scoped_release nogil;
    st = ParallelFor(n, threads, [&](size_t i) -> Status {
      std::vector<NearestHit> hits;
      MKTREE_RETURN_IF_ERROR(db.Nearest(
          Query::Nearest({p[3 * i], p[3 * i + 1], p[3 * i + 2]}, k, max_distance), &hits, nullptr));
      for (size_t j = 0; j < k; ++j) {
        const bool has = j < hits.size();
        id_out[i * k + j] = has ? int64_t{hits[j].id} : -1;
        d_out[i * k + j] = has ? hits[j].distance : std::numeric_limits<double>::infinity();
        for (int a = 0; a < 3; ++a)
          p_out[3 * (i * k + j) + a] = has ? hits[j].point[a] : std::numeric_limits<double>::quiet_NaN();
      }
      return Status::Ok();
    });
  }
  if (!st.ok()) Raise(st);
  return py::make_tuple(ids, dist, at);
}

// The first hit of each ray (rows of `origins` and `directions`, (n, 3) each): (ids int64 (n,), -1 for a
// miss; t float64 (n,), inf for a miss; points and normals float64 (n, 3), nan for a miss).
py::tuple RaysMany(const Database& db, const py::handle& origins_in, const py::handle& directions_in,
                   double max_length, unsigned threads) {
  auto origins = Rows(origins_in, 3, "origins");
  auto directions = Rows(directions_in, 3, "directions");
  if (origins.shape(0) != directions.shape(0))
    throw py::value_error("origins and directions must have the same number of rows");
  const size_t n = static_cast<size_t>(origins.shape(0));
  const py::ssize_t sn = static_cast<py::ssize_t>(n);
  py::array_t<int64_t> ids(sn);
  py::array_t<double> t(sn);
  py::array_t<double> points({sn, py::ssize_t{3}});
  py::array_t<double> normals({sn, py::ssize_t{3}});
  int64_t* id_out = ids.mutable_data();
  double* t_out = t.mutable_data();
  double* p_out = points.mutable_data();
  double* n_out = normals.mutable_data();
  const double* o = origins.data();
  const double* d = directions.data();
  Status st;
  {
    py::gil_scoped_release nogil;
    st = ParallelFor(n, threads, [&](size_t i) -> Status {
      std::vector<RayHit> hits;
      MKTREE_RETURN_IF_ERROR(db.Ray(Query::Ray({o[3 * i], o[3 * i + 1], o[3 * i + 2]},
                                               {d[3 * i], d[3 * i + 1], d[3 * i + 2]}, max_length),
                                    &hits, nullptr));
      const bool has = !hits.empty();
      id_out[i] = has ? int64_t{hits[0].id} : -1;
      t_out[i] = has ? hits[0].t : std::numeric_limits<double>::infinity();
      for (int a = 0; a < 3; ++a) {
        p_out[3 * i + a] = has ? hits[0].point[a] : std::numeric_limits<double>::quiet_NaN();
        n_out[3 * i + a] = has ? hits[0].normal[a] : std::numeric_limits<double>::quiet_NaN();
      }
      return Status::Ok();
    });
  }
  if (!st.ok()) Raise(st);
  return py::make_tuple(ids, t, points, normals);
}

py::array_t<double> BoundsArray(const Box3d& b) {
  py::array_t<double> a({2, 3});
  auto m = a.mutable_unchecked<2>();
  for (int i = 0; i < 3; ++i) {
    m(0, i) = b.min[i];
    m(1, i) = b.max[i];
  }
  return a;
}

// --- building ---

BuildOptions::Backend ParseBackend(const std::string& s) {
  if (s == "hdf5") return BuildOptions::Backend::kHdf5;
  if (s == "pagefile") return BuildOptions::Backend::kPagedFile;
  throw py::value_error("backend must be 'hdf5' or 'pagefile', not '" + s + "'");
}
BuildOptions::Codec ParseCodec(const std::string& s) {
  if (s == "zstd") return BuildOptions::Codec::kZstd;
  if (s == "none") return BuildOptions::Codec::kNone;
  throw py::value_error("codec must be 'zstd' or 'none', not '" + s + "'");
}
BuildOptions::SplitPolicy ParsePolicy(const std::string& s) {
  if (s == "compact") return BuildOptions::SplitPolicy::kCompact;
  if (s == "soa") return BuildOptions::SplitPolicy::kSoa;
  if (s == "soa-fill") return BuildOptions::SplitPolicy::kSoaFill;
  throw py::value_error("split_policy must be 'compact', 'soa' or 'soa-fill', not '" + s + "'");
}

// A field of a dict-like object, or an attribute of any other; None when absent.
py::object Field(py::handle obj, const char* name) {
  if (py::isinstance<py::dict>(obj)) {
    py::dict d = py::reinterpret_borrow<py::dict>(obj);
    return d.contains(name) ? py::reinterpret_borrow<py::object>(d[name]) : py::none();
  }
  return py::getattr(obj, name, py::none());
}

std::string Shape(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// One object of `objects` (a dict or an object with vertices [n, 3] float, faces [m, 3] integer, and
// optionally name, source and attributes; trimesh's Trimesh has its name in metadata["name"]) into `out`.
// InvalidArgument names the object's index; Python errors (a failing __getattr__) propagate.
Status ToSceneObject(py::handle item, uint64_t index, SceneObject* out) {
  const std::string what = "objects[" + std::to_string(index) + "]";
  py::object v = Field(item, "vertices"), f = Field(item, "faces");
  if (v.is_none() || f.is_none())
    return Status::InvalidArgument(what + ": no 'vertices' and 'faces' (a dict or an object with both)");
  auto verts = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(v);
  if (!verts || verts.ndim() != 2 || verts.shape(1) != 3)
    return Status::InvalidArgument(what + ": vertices must be a float array of shape (n, 3), not " +
                                   (verts ? Shape(verts) : std::string("convertible")));
  py::array faces_any = py::array::ensure(f);
  if (!faces_any) return Status::InvalidArgument(what + ": faces must be an integer array");
  const char kind = faces_any.dtype().kind();
  if (faces_any.size() != 0 && kind != 'i' && kind != 'u')  // float indices would be truncated
    return Status::InvalidArgument(what + ": faces must be an integer array, not of dtype " +
                                   py::str(faces_any.dtype()).cast<std::string>());
  auto faces = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(faces_any);
  if (!faces || faces.ndim() != 2 || faces.shape(1) != 3)
    return Status::InvalidArgument(what + ": faces must be an integer array of shape (m, 3), not " +
                                   Shape(faces_any));
  out->mesh.vertices.assign(verts.data(), verts.data() + verts.size());
  out->mesh.triangles.resize(static_cast<size_t>(faces.size()));
  const int64_t* fp = faces.data();
  for (py::ssize_t i = 0; i < faces.size(); ++i) {
    if (fp[i] < 0 || fp[i] > int64_t{UINT32_MAX})
      return Status::InvalidArgument(what + ": face " + std::to_string(i / 3) + " has vertex index " +
                                     std::to_string(fp[i]));
    out->mesh.triangles[static_cast<size_t>(i)] = static_cast<uint32_t>(fp[i]);
  }
  py::object name = Field(item, "name");
  if (name.is_none()) {
    py::object meta = Field(item, "metadata");
    if (py::isinstance<py::dict>(meta)) name = Field(meta, "name");
  }
  out->name = name.is_none() ? std::string() : Bytes(name);
  py::object source = Field(item, "source");
  out->source = source.is_none() ? std::string() : Bytes(source);
  out->attributes.clear();
  py::object attrs = Field(item, "attributes");
  if (!attrs.is_none()) {
    py::object pairs = py::isinstance<py::dict>(attrs) ? attrs.attr("items")() : attrs;
    for (py::handle kv : pairs) {
      py::tuple t = py::reinterpret_borrow<py::object>(kv).cast<py::tuple>();
      if (t.size() != 2) return Status::InvalidArgument(what + ": attributes must be (key, value) pairs");
      out->attributes.push_back({Bytes(t[0]), Bytes(t[1])});
    }
  }
  return Status::Ok();
}

// Thrown through the engine (which turns it into a Status) to stop a build whose Python callback raised.
struct PythonRaised {};

py::dict BuildStatsDict(const BuildStats& s) {
  py::dict d;
  d["objects"] = s.objects;
  d["triangles"] = s.triangles;
  d["leaves"] = s.leaves;
  d["pages"] = s.pages;
  d["page_bytes"] = s.page_bytes;
  d["height"] = s.height;
  d["mean_page_fill"] = s.mean_page_fill;
  d["origin"] = py::make_tuple(s.origin.x, s.origin.y, s.origin.z);
  d["raw_geometry_bytes"] = s.raw_geometry_bytes;
  d["encoded_bytes"] = s.encoded_bytes;
  d["store_bytes"] = s.store_bytes;
  d["read_seconds"] = s.read_seconds;
  d["build_seconds"] = s.build_seconds;
  d["write_seconds"] = s.write_seconds;
  d["total_seconds"] = s.total_seconds;
  py::list warnings;
  for (const std::string& w : s.warnings) warnings.append(Text(w));
  d["warnings"] = warnings;
  return d;
}

// Scene inputs as build takes them: one path (str, bytes or path-like) or an iterable of them.
std::vector<std::string> FileList(const py::object& files) {
  std::vector<std::string> inputs;
  if (py::isinstance<py::str>(files) || py::isinstance<py::bytes>(files) ||
      py::hasattr(files, "__fspath__")) {
    inputs.push_back(PathText(files));
  } else {
    for (py::handle f : files) inputs.push_back(PathText(f));
  }
  return inputs;
}

py::dict Build(const py::object& path, const py::object& objects, const py::object& files,
               const std::string& backend, const std::string& codec, int zstd_level, uint32_t block_size,
               uint32_t blocks_per_page, double balance_r, uint32_t split_budget,
               const std::string& split_policy, unsigned threads, const py::object& spill_dir,
               double chord_tolerance, double angular_deflection, const py::object& progress,
               uint32_t shards) {
  if (objects.is_none() == files.is_none()) throw py::value_error("give either objects or files");
  BuildOptions opts;
  opts.backend = ParseBackend(backend);
  opts.codec = ParseCodec(codec);
  opts.zstd_level = zstd_level;
  opts.block_size = block_size;
  opts.blocks_per_page = blocks_per_page;
  opts.balance_r = balance_r;
  opts.split_budget = split_budget;
  opts.split_policy = ParsePolicy(split_policy);
  opts.threads = threads;
  opts.shards = shards;
  if (!spill_dir.is_none()) opts.spill_dir = PathText(spill_dir);
  opts.chord_tolerance = chord_tolerance;
  opts.angular_deflection = angular_deflection;
  const std::string store = PathText(path);

  std::optional<py::error_already_set> raised;  // a callback's exception, raised again after the build
  if (!progress.is_none()) {
    opts.progress = [&](BuildStage stage, uint64_t done, uint64_t total) {
      py::gil_scoped_acquire gil;
      try {
        progress(BuildStageName(stage), done, total);
        if (PyErr_CheckSignals() != 0) throw py::error_already_set();  // Ctrl-C stops the build
      } catch (py::error_already_set& e) {
        raised = std::move(e);
        throw PythonRaised{};
      }
    };
  }

  Result<BuildStats> stats = Status::Internal("not run");
  if (!files.is_none()) {
    const std::vector<std::string> inputs = FileList(files);
    py::gil_scoped_release nogil;
    stats = BuildFromFiles(inputs, store, opts);
  } else {
    py::iterator it = py::iter(objects);
    uint64_t index = 0;
    const ObjectSource source = [&](SceneObject* out) -> Result<bool> {
      py::gil_scoped_acquire gil;
      try {
        if (PyErr_CheckSignals() != 0) throw py::error_already_set();
        if (index != 0) ++it;
        if (it == py::iterator::sentinel()) return false;
        MKTREE_RETURN_IF_ERROR(ToSceneObject(*it, index, out));
        ++index;
        return true;
      } catch (py::error_already_set& e) {
        raised = std::move(e);
        return Status::Internal("objects[" + std::to_string(index) + "]: a Python exception");
      }
    };
    py::gil_scoped_release nogil;
    stats = BuildFromObjects(source, store, opts);
  }
  if (raised) throw std::move(*raised);
  return BuildStatsDict(Take(std::move(stats)));
}

// --- changes ---

// A list of objects as ToSceneObject reads them, errors naming `what` ("add[3]: ..."); *has_id (may be
// null) says which carried an "id".
std::vector<SceneObject> SceneObjects(const py::object& objects, const std::string& what,
                                      std::vector<bool>* has_id = nullptr) {
  std::vector<SceneObject> out;
  if (objects.is_none()) return out;
  uint64_t index = 0;
  for (py::handle item : objects) {
    SceneObject o;
    const Status st = ToSceneObject(item, index, &o);
    if (!st.ok()) Raise(Status::InvalidArgument(what + st.message().substr(std::strlen("objects"))));
    py::object id = Field(item, "id");
    if (!id.is_none()) o.id = id.cast<uint32_t>();
    if (has_id) has_id->push_back(!id.is_none());
    out.push_back(std::move(o));
    ++index;
  }
  return out;
}

py::dict CommitDict(const CommitReport& r) {
  py::dict d;
  d["revision"] = r.revision;
  d["added"] = r.added;
  d["removed"] = r.removed;
  d["replaced"] = r.replaced;
  d["added_ids"] = IdArray(r.added_ids.data(), r.added_ids.size());
  d["objects"] = r.objects;
  d["compacted"] = r.compacted;
  d["compaction_error"] =
      r.compaction_error.empty() ? py::object(py::none()) : py::object(Text(r.compaction_error));
  d["seconds"] = r.seconds;
  py::list warnings;
  for (const std::string& w : r.warnings) warnings.append(Text(w));
  d["warnings"] = warnings;
  return d;
}

py::dict CompactDict(const CompactReport& r) {
  py::dict d;
  d["revision"] = r.revision;
  d["objects"] = r.objects;
  d["folded"] = r.folded;
  d["retired"] = r.retired;
  d["bytes_freed"] = r.bytes_freed;
  d["seconds"] = r.seconds;
  return d;
}

// The one writer of a store (mktree.open_writer); close() or leaving a `with` block releases the store's
// writer lock.
class PyWriter {
 public:
  explicit PyWriter(std::unique_ptr<ChangeWriter> w) : w_(std::move(w)) {}

  // replace: objects with an "id" replace that object; objects without one replace the one live object of
  // their name.
  py::dict Commit(const py::object& add, const py::object& add_files, const py::object& remove,
                  const py::object& remove_names, const py::object& replace, const std::string& message) {
    ChangeWriter& w = Open();
    ChangeBatch batch;
    batch.add = SceneObjects(add, "add");
    if (!add_files.is_none()) batch.add_files = FileList(add_files);
    std::vector<bool> by_id;
    std::vector<SceneObject> replacing = SceneObjects(replace, "replace", &by_id);
    for (size_t i = 0; i < replacing.size(); ++i)
      (by_id[i] ? batch.replace : batch.replace_by_name).push_back(std::move(replacing[i]));
    if (!remove.is_none())
      for (py::handle id : remove) batch.remove.push_back(id.cast<uint32_t>());
    if (!remove_names.is_none())
      for (py::handle name : remove_names) batch.remove_names.push_back(Bytes(name));
    batch.message = message;
    Result<CommitReport> r = Status::Internal("not run");
    {
      py::gil_scoped_release nogil;
      r = w.Commit(batch);
    }
    return CommitDict(Take(std::move(r)));
  }
  py::dict Compact(std::optional<uint32_t> keep) {
    ChangeWriter& w = Open();
    if (keep) {
      if (Status st = w.SetKeep(*keep); !st.ok()) Raise(st);
    }
    Result<CompactReport> r = Status::Internal("not run");
    {
      py::gil_scoped_release nogil;
      r = w.Compact();
    }
    return CompactDict(Take(std::move(r)));
  }
  void SetKeep(uint32_t keep) {
    if (Status st = Open().SetKeep(keep); !st.ok()) Raise(st);
  }
  uint64_t revision() { return Open().revision(); }
  void Close() { w_.reset(); }
  bool closed() const { return !w_; }

 private:
  ChangeWriter& Open() {
    if (!w_) Raise(Status::InvalidArgument("the writer is closed"));
    return *w_;
  }
  std::unique_ptr<ChangeWriter> w_;
};

py::list Log(const py::object& path) {
  const std::string p = PathText(path);
  Result<std::vector<RevisionInfo>> r = Status::Internal("not run");
  {
    py::gil_scoped_release nogil;
    r = ListRevisions(p);
  }
  py::list out;
  for (const RevisionInfo& i : Take(std::move(r))) {
    py::dict d;
    d["revision"] = i.revision;
    d["time"] = i.time;
    d["added"] = i.added;
    d["removed"] = i.removed;
    d["replaced"] = i.replaced;
    d["objects"] = i.objects;
    d["compaction"] = i.compaction;
    d["message"] = Text(i.message);
    out.append(d);
  }
  return out;
}

std::unique_ptr<PyWriter> OpenWriter(const py::object& path, double compact_threshold, unsigned threads) {
  ChangeOptions o;
  o.compact_threshold = compact_threshold;
  o.threads = threads;
  const std::string p = PathText(path);
  return std::make_unique<PyWriter>(Take([&] {
    py::gil_scoped_release nogil;
    return ChangeWriter::Open(p, o);
  }()));
}

// mktree.open and mktree.build.
// Clash pairs as numpy arrays: a, b (uint32; collide's b is 2**32 - 1), cls (uint8: 0 hard, 1 touch,
// 2 clearance), distance, depth_lower, depth_upper (float64), point_a, point_b (float64 (n, 3)).
py::dict PairArrays(const std::vector<const ClashPair*>& pairs) {
  const auto n = static_cast<py::ssize_t>(pairs.size());
  py::array_t<uint32_t> a(n), b(n);
  py::array_t<uint8_t> cls(n);
  py::array_t<double> distance(n), lower(n), upper(n), pa({n, py::ssize_t{3}}), pb({n, py::ssize_t{3}});
  for (py::ssize_t i = 0; i < n; ++i) {
    const ClashPair& p = *pairs[static_cast<size_t>(i)];
    a.mutable_data()[i] = p.a;
    b.mutable_data()[i] = p.b;
    cls.mutable_data()[i] = static_cast<uint8_t>(p.cls);
    distance.mutable_data()[i] = p.distance;
    lower.mutable_data()[i] = p.depth_lower;
    upper.mutable_data()[i] = p.depth_upper;
    for (int k = 0; k < 3; ++k) {
      pa.mutable_data()[3 * i + k] = p.point_a[k];
      pb.mutable_data()[3 * i + k] = p.point_b[k];
    }
  }
  py::dict d;
  d["a"] = a;
  d["b"] = b;
  d["cls"] = cls;
  d["distance"] = distance;
  d["depth_lower"] = lower;
  d["depth_upper"] = upper;
  d["point_a"] = pa;
  d["point_b"] = pb;
  return d;
}

py::dict ClashStatsDict(const ClashStats& s) {
  py::dict d;
  d["pages_read"] = s.pages_read;
  d["store_pages"] = s.store_pages;
  d["leaf_reads"] = s.leaf_reads;
  d["leaf_pairs_visited"] = s.leaf_pairs_visited;
  d["candidate_pairs"] = s.candidate_pairs;
  d["excluded_pairs"] = s.excluded_pairs;
  d["hard"] = s.hard;
  d["touch"] = s.touch;
  d["clearance"] = s.clearance;
  d["capped_pairs"] = s.capped_pairs;
  d["seconds"] = s.total_seconds;
  return d;
}

ClashOptions MakeClashOptions(double clearance, double touch_tolerance, unsigned threads, bool report_touch,
                              const std::string& exclude_group) {
  ClashOptions o;
  o.clearance = clearance;
  o.touch_tolerance = touch_tolerance;
  o.threads = threads;
  o.report_touch = report_touch;
  o.exclude_group_separator = exclude_group;
  return o;
}

py::dict PlainPairs(const std::vector<ClashPair>& pairs, const ClashStats& stats) {
  std::vector<const ClashPair*> ptrs;
  for (const ClashPair& p : pairs) ptrs.push_back(&p);
  py::dict d = PairArrays(ptrs);
  d["stats"] = ClashStatsDict(stats);
  return d;
}

// A clash-test file from a dict (its JSON) or a path.
ClashTestFile TestsFrom(const py::handle& tests) {
  if (py::isinstance<py::dict>(tests)) {
    const std::string text = py::module_::import("json").attr("dumps")(tests).cast<std::string>();
    return Take(ParseClashTests(text, "<tests dict>"));
  }
  const std::string path = PathText(tests);
  py::gil_scoped_release nogil;
  return Take(ReadClashTests(path));
}

py::dict SummaryDict(const ClashTestSummary& s) {
  py::dict d, rules;
  for (const auto& [rule, n] : s.excluded_by_rule) rules[Text(rule)] = n;
  py::list warnings;
  for (const std::string& w : s.warnings) warnings.append(Text(w));
  d["name"] = Text(s.name);
  d["mode"] = s.mode;
  d["fingerprint"] = s.fingerprint;
  d["selected_a"] = s.selected_a;
  d["selected_b"] = s.selected_b;
  d["hard"] = s.hard;
  d["touch"] = s.touch;
  d["clearance"] = s.clearance_pairs;
  d["duplicates"] = s.duplicates;
  d["new"] = s.new_clashes;
  d["active"] = s.active;
  d["resolved"] = s.resolved;
  d["groups"] = s.groups;
  d["excluded_by_rule"] = rules;
  d["warnings"] = warnings;
  d["stats"] = ClashStatsDict(s.stats);
  return d;
}

// The run's clashes (resolved ones included, status "resolved") as arrays, with test, key, group and
// status lists per pair, the test summaries and the groups.
py::dict RunArrays(const ClashRun& run) {
  std::vector<const ClashPair*> pairs;
  py::list test, key, group, status, id_a, id_b;
  for (const ClashGroup& g : run.groups)
    for (const ClashRecord& r : g.members) {
      pairs.push_back(&r.pair);
      test.append(Text(g.test));
      key.append(r.key);
      group.append(g.key);
      status.append(ClashStatusName(r.status));
      id_a.append(Text(r.a->stable));
      id_b.append(Text(r.b->stable));
    }
  py::dict d = PairArrays(pairs);
  d["test"] = test;
  d["key"] = key;
  d["group"] = group;
  d["status"] = status;
  d["id_a"] = id_a;
  d["id_b"] = id_b;
  py::list tests, groups;
  for (const ClashTestSummary& s : run.tests) tests.append(SummaryDict(s));
  for (const ClashGroup& g : run.groups) {
    py::dict gd;
    gd["key"] = g.key;
    gd["test"] = Text(g.test);
    gd["title"] = Text(g.title);
    gd["centre"] = py::make_tuple(g.centre.x, g.centre.y, g.centre.z);
    gd["box"] = BoundsArray(g.box);
    gd["worst"] = ClashClassName(g.worst);
    gd["worst_distance"] = g.worst_distance;
    gd["status"] = ClashStatusName(g.status);
    gd["members"] = g.members.size();
    groups.append(gd);
  }
  d["tests"] = tests;
  d["groups"] = groups;
  return d;
}

py::dict Clash(const Database& db, const py::object& tests, const py::object& previous, double clearance,
               double touch_tolerance, unsigned threads, bool report_touch,
               const std::string& exclude_group) {
  if (tests.is_none()) {
    if (!previous.is_none()) throw py::value_error("previous goes with tests");
    const ClashOptions o = MakeClashOptions(clearance, touch_tolerance, threads, report_touch, exclude_group);
    std::vector<ClashPair> pairs;
    ClashStats stats;
    Status st;
    {
      py::gil_scoped_release nogil;
      st = db.SelfClash(
          o, [&](const ClashPair& p) { pairs.push_back(p); }, &stats);
    }
    if (!st.ok()) Raise(st);
    return PlainPairs(pairs, stats);
  }
  const ClashTestFile file = TestsFrom(tests);
  ClashTestOptions o;
  o.threads = threads;
  PreviousClashRun before;
  if (!previous.is_none()) {
    const std::string path = PathText(previous);
    py::gil_scoped_release nogil;
    before = Take(ReadPreviousClashRun(path));
  }
  if (!previous.is_none()) o.previous = &before;
  ClashRun run;
  Status st;
  {
    py::gil_scoped_release nogil;
    st = RunClashTests(db, file, o, &run);
  }
  if (!st.ok()) Raise(st);
  return RunArrays(run);
}

// A 4 x 4 matrix [R t; 0 1] as a rigid transform (the engine checks that R is a rotation).
std::optional<RigidTransform> TransformFrom(const py::object& t) {
  if (t.is_none()) return std::nullopt;
  auto m = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(t);
  if (!m || m.ndim() != 2 || m.shape(0) != 4 || m.shape(1) != 4)
    throw py::value_error("transform must be a 4 x 4 matrix [R t; 0 1]");
  RigidTransform r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r.rotation[3 * i + j] = m.at(i, j);
    r.translation[i] = m.at(i, 3);
  }
  return r;
}

py::dict Collide(const Database& db, const py::object& vertices, const py::object& faces,
                 const py::object& transform, double clearance, double touch_tolerance, unsigned threads,
                 bool report_touch) {
  py::dict item;
  item["vertices"] = vertices;
  item["faces"] = faces;
  SceneObject object;
  if (Status st = ToSceneObject(item, 0, &object); !st.ok()) Raise(st);
  const std::optional<RigidTransform> moved = TransformFrom(transform);
  const ClashOptions o = MakeClashOptions(clearance, touch_tolerance, threads, report_touch, "");
  std::vector<ClashPair> pairs;
  ClashStats stats;
  Status st;
  {
    py::gil_scoped_release nogil;
    st = db.Collide(
        object.mesh, moved, o, [&](const ClashPair& p) { pairs.push_back(p); }, &stats);
  }
  if (!st.ok()) Raise(st);
  return PlainPairs(pairs, stats);
}

void DefineClash(py::class_<Database>& c) {
  c.def("clash", &Clash, py::kw_only(), py::arg("tests") = py::none(), py::arg("previous") = py::none(),
        py::arg("clearance") = 0.0, py::arg("touch_tolerance") = 0.002, py::arg("threads") = 0,
        py::arg("report_touch") = true, py::arg("exclude_group") = "",
        "The self-clash (tests None: dict of arrays a, b, cls, distance, depth_lower, depth_upper, point_a, "
        "point_b and stats), or the clash tests of a file path or dict (docs/clash_workflow.md): the same "
        "arrays plus per pair test, key, group, status, id_a, id_b lists, the tests' summaries and the "
        "groups; previous: a previous run's JSON lines to compare with (statuses new, active, resolved)");
  c.def("collide", &Collide, py::arg("vertices"), py::arg("faces"), py::arg("transform") = py::none(),
        py::kw_only(), py::arg("clearance") = 0.0, py::arg("touch_tolerance") = 0.002, py::arg("threads") = 0,
        py::arg("report_touch") = true,
        "The store's objects that clash with the mesh (vertices (n, 3), faces (m, 3)) moved by transform (a "
        "4 x 4 matrix [R t; 0 1], R a rotation; None: as it is): dict of arrays as clash's, b = 2**32 - 1");
}

void DefineOpenAndBuild(py::module_& m) {
  m.def(
      "open",
      [](const py::object& path, uint64_t cache_pages, bool verify_checksums, bool direct_io,
         std::optional<uint64_t> revision) {
        OpenOptions o;
        o.cache_pages = cache_pages;
        o.verify_checksums = verify_checksums;
        o.direct_io = direct_io;
        o.revision = revision;
        const std::string p = PathText(path);
        return Take([&] {
          py::gil_scoped_release nogil;
          return Database::Open(p, o);
        }());
      },
      py::arg("path"), py::arg("cache_pages") = 4096, py::arg("verify_checksums") = true,
      py::arg("direct_io") = false, py::arg("revision") = py::none(),
      "Opens a store (HDF5 or paged file) for queries, at `revision` (None: the newest) while the store "
      "keeps it");

  m.def("build", &Build, py::arg("path"), py::arg("objects") = py::none(), py::arg("files") = py::none(),
        py::kw_only(), py::arg("backend") = "hdf5", py::arg("codec") = "zstd", py::arg("zstd_level") = 3,
        py::arg("block_size") = 4096, py::arg("blocks_per_page") = 3, py::arg("balance_r") = 0.3,
        py::arg("split_budget") = 64, py::arg("split_policy") = "compact", py::arg("threads") = 0,
        py::arg("spill_dir") = py::none(), py::arg("chord_tolerance") = BuildOptions{}.chord_tolerance,
        py::arg("angular_deflection") = BuildOptions{}.angular_deflection, py::arg("progress") = py::none(),
        py::arg("shards") = 0,
        "Builds the store at `path` from `objects` (an iterable of dicts or objects with vertices (n, 3), "
        "faces (m, 3), optional name and attributes) or `files` (a path or a list: any format mktree "
        "build reads, or 'tanker:N:SEED'); with `shards` K > 0, a sharded store of K shards (`path` is its "
        "manifest). Returns the build statistics as a dict.");
}

// The change API (mktree/changes.h): the Writer class, open_writer and log.
void DefineChanges(py::module_& m) {
  py::class_<PyWriter>(m, "Writer", "The one writer of a store (mktree.open_writer); one thread at a time")
      .def("commit", &PyWriter::Commit, py::kw_only(), py::arg("add") = py::none(),
           py::arg("add_files") = py::none(), py::arg("remove") = py::none(),
           py::arg("remove_names") = py::none(), py::arg("replace") = py::none(), py::arg("message") = "",
           "Commits one batch, all or nothing, as one new revision: `add` objects (as build takes them) get "
           "new ids, then the objects of `add_files` (a path or a list, as build's `files`; streamed, never "
           "all in memory); `remove` ids and every live object of each of `remove_names` go; each object of "
           "`replace` replaces the object of its 'id', or without one the one live object of its name. "
           "Returns a dict: revision, added, removed, replaced, added_ids, objects, compacted, "
           "compaction_error, seconds, warnings (the readers' of add_files)")
      .def("compact", &PyWriter::Compact, py::kw_only(), py::arg("keep") = py::none(),
           "Folds every change into a new base now (after set_keep(keep) if given). Returns a dict: "
           "revision, objects, folded, retired, bytes_freed, seconds")
      .def("set_keep", &PyWriter::SetKeep, py::arg("keep"),
           "How many of the newest revisions the store keeps from the next commit or compaction on")
      .def_property_readonly("revision", &PyWriter::revision, "The newest committed revision")
      .def_property_readonly("closed", &PyWriter::closed)
      .def("close", &PyWriter::Close, "Releases the store's writer lock")
      .def(
          "__enter__", [](PyWriter& w) -> PyWriter& { return w; }, py::return_value_policy::reference)
      .def("__exit__", [](PyWriter& w, py::args) { w.Close(); });

  m.def(
      "open_writer", &OpenWriter, py::arg("path"), py::kw_only(), py::arg("compact_threshold") = 0.25,
      py::arg("threads") = 0,
      "Opens the one writer of a store (a second, in this process or another, raises mktree.Error at once)");
  m.def("log", &Log, py::arg("path"),
        "The revisions the store keeps, oldest first: dicts with revision, time (seconds since the epoch), "
        "added, removed, replaced, objects, compaction, message");
}

// db.nearest and db.rays (docs/nearest_and_ray.md), added to the Database class defined above.
void DefineNearest(py::module_& m) {
  auto cls = py::reinterpret_borrow<py::class_<Database>>(m.attr("Database"));
  cls.def(
         "nearest",
         [](const Database& db, const py::handle& points, uint64_t k, double max_distance, unsigned threads) {
           return NearestMany(db, points, k, max_distance, threads);
         },
         py::arg("points"), py::arg("k") = 1,
         py::arg("max_distance") = std::numeric_limits<double>::infinity(), py::arg("threads") = 0,
         "The k nearest objects of each point of an (n, 3) array, by exact distance (0 inside a solid), on "
         "`threads` threads: (ids int64 (n, k), -1 past the answer; distances (n, k), inf past it; closest "
         "points (n, k, 3), nan past it)")
      .def(
          "rays",
          [](const Database& db, const py::handle& origins, const py::handle& directions, double max_length,
             unsigned threads) { return RaysMany(db, origins, directions, max_length, threads); },
          py::arg("origins"), py::arg("directions"),
          py::arg("max_length") = std::numeric_limits<double>::infinity(), py::arg("threads") = 0,
          "The first hit of each ray (origins and directions: (n, 3) arrays; a direction need not be unit): "
          "(ids int64 (n,), -1 for a miss; t (n,) distance along the ray, inf for a miss; points (n, 3) "
          "and triangle normals (n, 3), nan for a miss)");
}

}  // namespace
}  // namespace mktree

PYBIND11_MODULE(mktree, m) {
  using namespace mktree;
  namespace py = pybind11;
  m.doc() = "mktree: an out-of-core 3D spatial database (docs/python.md)";
  m.attr("__version__") = MKTREE_VERSION_STRING;
  py::register_exception<Error>(m, "Error", PyExc_RuntimeError);

  py::class_<Database> database(m, "Database", "An open store; safe to query from many threads at once");
  DefineClash(database);
  database.def_property_readonly("path", [](const Database& db) { return Text(db.path()); })
      .def_property_readonly("object_count", &Database::object_count, "Live objects")
      .def_property_readonly("revision", &Database::revision,
                             "The revision this Database answers for as long as it is open (0: no change)")
      .def_property_readonly("id_limit", &Database::id_limit, "Above every id of this revision")
      .def_property_readonly(
          "bounds", [](const Database& db) { return BoundsArray(db.bounds()); },
          "Scene bounds, [[min x, y, z], [max x, y, z]] (float64, rounded outward to float32)")
      .def(
          "point",
          [](const Database& db, double x, double y, double z, bool exact, std::optional<uint64_t> limit,
             bool stats) {
            return RunOne(db, Query::Point({x, y, z}, Mode(exact)), limit, stats);
          },
          py::arg("x"), py::arg("y"), py::arg("z"), py::arg("exact") = false, py::arg("limit") = py::none(),
          py::arg("stats") = false,
          "Ids (sorted uint32 array) of the objects containing the point; with stats=True, (ids, dict)")
      .def(
          "box",
          [](const Database& db, std::array<double, 3> min, std::array<double, 3> max, bool exact,
             std::optional<uint64_t> limit,
             bool stats) { return RunOne(db, MakeQuery(min, max, exact), limit, stats); },
          py::arg("min"), py::arg("max"), py::arg("exact") = false, py::arg("limit") = py::none(),
          py::arg("stats") = false, "Ids (sorted uint32 array) of the objects meeting the closed box")
      .def(
          "points",
          [](const Database& db, const py::handle& rows, bool exact, unsigned threads, bool csr,
             std::optional<uint64_t> limit) { return RunMany(db, rows, 3, exact, threads, csr, limit); },
          py::arg("points"), py::arg("exact") = false, py::arg("threads") = 0, py::arg("csr") = false,
          py::arg("limit") = py::none(),
          "Point queries of an (n, 3) array on `threads` threads (0: one per core): a list of n uint32 "
          "arrays, or with csr=True (offsets, ids)")
      .def(
          "boxes",
          [](const Database& db, const py::handle& rows, bool exact, unsigned threads, bool csr,
             std::optional<uint64_t> limit) { return RunMany(db, rows, 6, exact, threads, csr, limit); },
          py::arg("boxes"), py::arg("exact") = false, py::arg("threads") = 0, py::arg("csr") = false,
          py::arg("limit") = py::none(), "Box queries of an (n, 6) array (min x, y, z, max x, y, z)")
      .def(
          "any",
          [](const Database& db, std::array<double, 3> min, std::optional<std::array<double, 3>> max,
             bool exact) {
            const Query q = MakeQuery(min, max, exact);
            return Take([&] {
              py::gil_scoped_release nogil;
              return db.Any(q, nullptr);
            }());
          },
          py::arg("min"), py::arg("max") = py::none(), py::arg("exact") = false,
          "Whether anything answers the point `min` (max None) or the box; reads pages up to the first hit")
      .def(
          "count",
          [](const Database& db, std::array<double, 3> min, std::optional<std::array<double, 3>> max,
             bool exact) {
            const Query q = MakeQuery(min, max, exact);
            uint64_t n = 0;
            Status st;
            {
              py::gil_scoped_release nogil;
              st = db.Visit(
                  q, [&n](ObjectId) { ++n; }, nullptr);
            }
            if (!st.ok()) Raise(st);
            return n;
          },
          py::arg("min"), py::arg("max") = py::none(), py::arg("exact") = false,
          "How many objects answer the point `min` (max None) or the box, without holding their ids")
      .def(
          "object_name", [](const Database& db, uint32_t id) { return Text(Take(db.ObjectName(id))); },
          py::arg("id"))
      .def(
          "object",
          [](const Database& db, uint32_t id) {
            Result<ObjectRecord> r = Status::Internal("unset");
            {
              py::gil_scoped_release nogil;
              r = db.Object(id);
            }
            const ObjectRecord rec = Take(std::move(r));
            py::list attributes;  // pairs, not a dict: a key may repeat (an OBJ object in two groups)
            for (const ObjectAttribute& a : rec.attributes)
              attributes.append(py::make_tuple(Text(a.key), Text(a.value)));
            py::dict d;
            d["id"] = rec.id;
            d["name"] = Text(rec.name);
            d["source"] = Text(rec.source);
            d["attributes"] = attributes;
            d["box"] = BoundsArray(rec.box);
            return d;
          },
          py::arg("id"),
          "The object's record: name, source file, attributes as (key, value) pairs and world box "
          "[[min], [max]]; one record page read")
      .def(
          "geometry",
          [](const Database& db, uint32_t id) {
            Result<Mesh> r = Status::Internal("unset");
            {
              py::gil_scoped_release nogil;
              r = db.ObjectGeometry(id);
            }
            const Mesh mesh = Take(std::move(r));
            py::array_t<double> vertices({static_cast<py::ssize_t>(mesh.vertex_count()), py::ssize_t{3}});
            py::array_t<uint32_t> faces({static_cast<py::ssize_t>(mesh.triangle_count()), py::ssize_t{3}});
            if (!mesh.vertices.empty())
              std::memcpy(vertices.mutable_data(), mesh.vertices.data(),
                          mesh.vertices.size() * sizeof(double));
            if (!mesh.triangles.empty())
              std::memcpy(faces.mutable_data(), mesh.triangles.data(),
                          mesh.triangles.size() * sizeof(uint32_t));
            return py::make_tuple(vertices, faces);
          },
          py::arg("id"),
          "The object's stored mesh as (vertices float64 (n, 3) in world coordinates, faces uint32 (m, 3)); "
          "reads its leaf")
      .def(
          "stats",
          [](const Database& db) {
            py::dict d;
            d["path"] = Text(db.path());
            d["object_count"] = db.object_count();
            d["objects_per_page"] = db.objects_per_page();
            d["bounds"] = BoundsArray(db.bounds());
            d["tree"] = db.stats_json().empty() ? py::object(py::none())
                                                : py::module_::import("json").attr("loads")(db.stats_json());
            return d;
          },
          "The store's statistics: the builder's tree statistics (mktree info --json's \"tree\") and more")
      .def(
          "clear_cache", [](Database& db) { db.ClearCache(); }, "Empties the page cache")
      .def("__repr__", [](const Database& db) {
        return "<mktree.Database '" + db.path() + "', revision " + std::to_string(db.revision()) + ", " +
               std::to_string(db.object_count()) + " objects>";
      });

  DefineOpenAndBuild(m);
  DefineChanges(m);
  DefineNearest(m);
}
