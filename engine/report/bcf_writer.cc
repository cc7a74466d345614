#include "engine/report/bcf_writer.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zip.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <map>
#include <memory>
#include <set>

#include "engine/report/report_text.h"
#include "engine/report/uuid_v5.h"
#include "engine/report/xml_element.h"
#include "storage/atomic_file.h"

namespace mktree {

const char* BcfVersionId(BcfVersion v) { return v == BcfVersion::k3_0 ? "3.0" : "2.1"; }

namespace {

// The namespace of every name-based GUID mktree gives BCF: UUID v5 of this URN in RFC 4122's URL namespace.
const std::string& BcfNamespace() {
  static const std::string ns = UuidV5(kUuidUrlNamespace, "urn:mktree:bcf");
  return ns;
}

std::string Number(double v) {
  if (!std::isfinite(v)) v = 0;
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

const char* ClassColour(ClashClass c) {  // as engine/viz/clash_render.h draws the classes
  switch (c) {
    case ClashClass::kHard:
      return "E11919";
    case ClashClass::kTouch:
      return "FA8200";
    case ClashClass::kClearance:
      return "EBC800";
  }
  return "E11919";
}

// BCF's IfcGuid: 22 characters of IFC's base-64 alphabet.
bool IsIfcGuid(const std::string& s) {
  if (s.size() != 22) return false;
  for (char c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '$') return false;
  return true;
}

// BCF 3.0 refuses empty or blank strings where it asks for one.
bool Blank(const std::string& s) { return s.find_first_not_of(" \t\r\n") == std::string::npos; }

std::string ComponentId(const ObjectIdentity& o) {
  if (IsIfcGuid(o.global_id)) return o.global_id;
  if (!Blank(o.name)) return o.name;
  return Blank(o.stable) ? "" : o.stable;
}

std::string Description(const ClashGroup& g, uint32_t listed) {
  std::string d = std::string(ClashClassName(g.worst)) + " clash group of test '" + g.test +
                  "': " + std::to_string(g.members.size()) + (g.members.size() == 1 ? " clash" : " clashes");
  if (const ClashRecord* worst = report::WorstMember(g))
    d += ", worst " + std::string(ClashClassName(worst->pair.cls)) + " " + report::DepthOrGap(worst->pair);
  d += ".";
  if (g.status != ClashStatus::kNone) d += " Status: " + std::string(ClashStatusName(g.status)) + ".";
  size_t n = 0;
  for (const ClashRecord& r : g.members) {
    if (n == listed) break;
    d += '\n';
    d += std::to_string(++n) + ". " + ClashClassName(r.pair.cls) + ", " + report::DepthOrGap(r.pair) + ": " +
         report::ObjectLine(*r.a) + " and " + report::ObjectLine(*r.b);
    if (r.status != ClashStatus::kNone) d += " [" + std::string(ClashStatusName(r.status)) + "]";
  }
  if (g.members.size() > n) d += "\n(and " + std::to_string(g.members.size() - n) + " more)";
  return d;
}

Vec3d Normalized(Vec3d v) {
  const double n = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return n > 0 ? Vec3d{v.x / n, v.y / n, v.z / n} : Vec3d{0, 0, 1};
}

void AppendPoint(std::string* x, const char* tag, const Vec3d& p) {
  *x += std::string("<") + tag + "><X>" + Number(p.x) + "</X><Y>" + Number(p.y) + "</Y><Z>" + Number(p.z) +
        "</Z></" + tag + ">";
}

void AppendComponent(std::string* x, const std::string& id) {
  if (IsIfcGuid(id))
    *x += "<Component IfcGuid=\"" + id + "\"/>";
  else
    *x += "<Component><AuthoringToolId>" + XmlEscape(id) + "</AuthoringToolId></Component>";
}

std::string ViewpointXml(const BcfViewpoint& v, BcfVersion version) {
  const bool v3 = version == BcfVersion::k3_0;
  std::string x = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<VisualizationInfo Guid=\"" + v.guid + "\">";
  x += "<Components>";
  if (!v3)
    x += "<ViewSetupHints SpacesVisible=\"false\" SpaceBoundariesVisible=\"false\" "
         "OpeningsVisible=\"false\"/>";
  if (!v.selected.empty()) {
    x += "<Selection>";
    for (const std::string& id : v.selected) AppendComponent(&x, id);
    x += "</Selection>";
  }
  if (v3)
    x += "<Visibility DefaultVisibility=\"true\"><ViewSetupHints SpacesVisible=\"false\" "
         "SpaceBoundariesVisible=\"false\" OpeningsVisible=\"false\"/></Visibility>";
  else
    x += "<Visibility DefaultVisibility=\"true\"/>";
  if (!v.colours.empty()) {
    x += "<Coloring>";
    for (const BcfColouring& c : v.colours) {
      x += "<Color Color=\"" + c.colour + "\">" + (v3 ? "<Components>" : "");
      for (const std::string& id : c.components) AppendComponent(&x, id);
      x += std::string(v3 ? "</Components>" : "") + "</Color>";
    }
    x += "</Coloring>";
  }
  x += "</Components><PerspectiveCamera>";
  AppendPoint(&x, "CameraViewPoint", v.camera.position);
  AppendPoint(&x, "CameraDirection", v.camera.direction);
  AppendPoint(&x, "CameraUpVector", v.camera.up);
  x += "<FieldOfView>" + Number(v.camera.field_of_view) + "</FieldOfView>";
  if (v3) x += "<AspectRatio>" + Number(v.camera.aspect_ratio) + "</AspectRatio>";
  x += "</PerspectiveCamera></VisualizationInfo>\n";
  return x;
}

std::string MarkupXml(const BcfTopic& t, BcfVersion version) {
  const bool v3 = version == BcfVersion::k3_0;
  std::string x = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Markup>";
  if (!t.files.empty()) {
    x += v3 ? "<Header><Files>" : "<Header>";
    for (const std::string& f : t.files)
      x += std::string("<File ") + (v3 ? "IsExternal" : "isExternal") + "=\"true\"><Filename>" +
           XmlEscape(f) + "</Filename></File>";
    x += v3 ? "</Files></Header>" : "</Header>";
  }
  x += "<Topic Guid=\"" + t.guid + "\" TopicType=\"" + XmlEscape(t.type) + "\" TopicStatus=\"" +
       XmlEscape(t.status) + "\"><Title>" + XmlEscape(t.title) + "</Title>";
  if (v3 && !t.labels.empty()) x += "<Labels>";
  for (const std::string& l : t.labels)
    x += (v3 ? "<Label>" : "<Labels>") + XmlEscape(l) + (v3 ? "</Label>" : "</Labels>");
  if (v3 && !t.labels.empty()) x += "</Labels>";
  x += "<CreationDate>" + t.creation_date + "</CreationDate><CreationAuthor>" + XmlEscape(t.author) +
       "</CreationAuthor>";
  if (!t.description.empty()) x += "<Description>" + XmlEscape(t.description) + "</Description>";
  std::string viewpoints;
  for (const BcfViewpoint& v : t.viewpoints) {
    viewpoints += std::string(v3 ? "<ViewPoint" : "<Viewpoints") + " Guid=\"" + v.guid + "\"><Viewpoint>" +
                  XmlEscape(v.file) + "</Viewpoint>";
    if (!v.snapshot_file.empty()) viewpoints += "<Snapshot>" + XmlEscape(v.snapshot_file) + "</Snapshot>";
    viewpoints += v3 ? "</ViewPoint>" : "</Viewpoints>";
  }
  if (v3) {
    if (!viewpoints.empty()) x += "<Viewpoints>" + viewpoints + "</Viewpoints>";
    x += "</Topic>";
  } else {
    x += "</Topic>" + viewpoints;
  }
  x += "</Markup>\n";
  return x;
}

std::string VersionXml(BcfVersion v) {
  if (v == BcfVersion::k3_0)
    return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Version VersionId=\"3.0\"/>\n";
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Version VersionId=\"2.1\"><DetailedVersion>2.1"
         "</DetailedVersion></Version>\n";
}

std::string ProjectXml(const ClashRun& run, const BcfOptions& o) {
  std::string name = o.project_name;
  if (name.empty()) name = std::filesystem::path(run.store).filename().string();
  if (Blank(name)) name = "mktree clash run";
  const std::string id = UuidV5(BcfNamespace(), "project:" + name);
  const std::string project =
      "<Project ProjectId=\"" + id + "\"><Name>" + XmlEscape(name) + "</Name></Project>";
  if (o.version == BcfVersion::k3_0)
    return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<ProjectInfo>" + project + "</ProjectInfo>\n";
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<ProjectExtension>" + project +
         "<ExtensionSchema></ExtensionSchema></ProjectExtension>\n";
}

std::string ExtensionsXml(const ClashRun& run, const BcfOptions& o) {
  std::string x =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Extensions><TopicTypes><TopicType>Clash"
      "</TopicType></TopicTypes><TopicStatuses><TopicStatus>" +
      XmlEscape(o.open_status) + "</TopicStatus>";
  if (o.closed_status != o.open_status) x += "<TopicStatus>" + XmlEscape(o.closed_status) + "</TopicStatus>";
  x += "</TopicStatuses><TopicLabels>";
  std::set<std::string> labels = {"hard", "touch", "clearance", "new", "active", "resolved"};
  for (const ClashTestSummary& t : run.tests)
    if (!Blank(t.name)) labels.insert(t.name);
  for (const std::string& l : labels) x += "<TopicLabel>" + XmlEscape(l) + "</TopicLabel>";
  x += "</TopicLabels><Users><User>" + XmlEscape(o.author) + "</User></Users></Extensions>\n";
  return x;
}

}  // namespace

std::string BcfDateTime(int64_t t) {
  const time_t tt = static_cast<time_t>(t);
  struct tm tm {};
  gmtime_r(&tt, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string BcfTopicGuid(const std::string& group_key) { return UuidV5(BcfNamespace(), group_key); }
std::string BcfViewpointGuid(const std::string& group_key) {
  return UuidV5(BcfNamespace(), group_key + "/viewpoint");
}

BcfCamera BcfCameraFraming(const Box3d& box, double field_of_view, double aspect_ratio) {
  BcfCamera c;
  c.field_of_view = field_of_view;
  c.aspect_ratio = aspect_ratio;
  Vec3d centre{0, 0, 0};
  double radius = 1;
  if (!box.empty()) {
    centre = {(box.min[0] + box.max[0]) / 2, (box.min[1] + box.max[1]) / 2, (box.min[2] + box.max[2]) / 2};
    const double dx = box.max[0] - box.min[0], dy = box.max[1] - box.min[1], dz = box.max[2] - box.min[2];
    radius = std::max(0.5, std::sqrt(dx * dx + dy * dy + dz * dz) / 2);
  }
  // The sphere fits the narrower of the two fields of view, with a margin of 10 %.
  const double half_v = field_of_view * M_PI / 360;
  const double half = std::min(half_v, std::atan(std::tan(half_v) * aspect_ratio));
  const double distance = 1.1 * radius / std::sin(half);
  const Vec3d toward_viewer = Normalized({1, -1, 1});
  c.position = {centre.x + distance * toward_viewer.x, centre.y + distance * toward_viewer.y,
                centre.z + distance * toward_viewer.z};
  c.direction = {-toward_viewer.x, -toward_viewer.y, -toward_viewer.z};
  const double along = c.direction.z;  // up = +z made orthogonal to the direction
  c.up = Normalized({-along * c.direction.x, -along * c.direction.y, 1 - along * c.direction.z});
  return c;
}

BcfTopic BcfTopicOf(const ClashGroup& g, const BcfOptions& o, bool with_snapshot) {
  BcfTopic t;
  t.guid = BcfTopicGuid(g.key);
  t.type = "Clash";
  t.status = g.status == ClashStatus::kResolved ? o.closed_status : o.open_status;
  t.title = g.title;
  if (t.title.empty() && !g.members.empty())
    t.title = std::string(ClashClassName(g.worst)) + ": " + report::ObjectLine(*g.members[0].a) + " and " +
              report::ObjectLine(*g.members[0].b);
  if (Blank(t.title)) t.title = "Clash group " + g.key;
  t.description = Description(g, o.listed_members);
  t.creation_date = BcfDateTime(o.creation_time);
  t.author = o.author;
  t.labels.push_back(ClashClassName(g.worst));
  if (!Blank(g.test)) t.labels.push_back(g.test);
  if (g.status != ClashStatus::kNone) t.labels.push_back(ClashStatusName(g.status));
  BcfViewpoint v;
  v.guid = BcfViewpointGuid(g.key);
  if (with_snapshot) v.snapshot_file = "snapshot.png";
  v.camera = BcfCameraFraming(g.box, o.field_of_view, o.aspect_ratio);
  // Each object once, in the colour of its worst class in the group; the members are in key order.
  std::map<std::string, ClashClass> worst;
  std::set<std::string> files;
  auto add = [&](const ObjectIdentity& obj, ClashClass c) {
    const std::string file = std::filesystem::path(obj.source).filename().string();
    if (!Blank(file)) files.insert(file);
    const std::string id = ComponentId(obj);
    if (id.empty()) return;
    auto [it, inserted] = worst.emplace(id, c);
    if (inserted) {
      if (v.selected.size() < o.max_components) v.selected.push_back(id);
    } else if (report::ClassRank(c) < report::ClassRank(it->second)) {
      it->second = c;
    }
  };
  for (const ClashRecord& r : g.members) add(*r.a, r.pair.cls), add(*r.b, r.pair.cls);
  for (ClashClass c : {ClashClass::kHard, ClashClass::kTouch, ClashClass::kClearance}) {
    BcfColouring colouring{ClassColour(c), {}};
    for (const std::string& id : v.selected)
      if (worst[id] == c) colouring.components.push_back(id);
    if (!colouring.components.empty()) v.colours.push_back(std::move(colouring));
  }
  t.files.assign(files.begin(), files.end());
  t.viewpoints.push_back(std::move(v));
  return t;
}

namespace {

// An archive entry whose bytes are made when libzip writes it (at zip_close) and dropped once written, so
// that the archive's memory is one entry's, whatever the number of topics and snapshots.
struct LazyEntry {
  std::function<Status(std::vector<uint8_t>*)> make;
  Status* first_error;  // shared by the entries of one archive: the first failure, for the caller
  std::vector<uint8_t> bytes;
  bool made = false;
  bool size_known = false;
  uint64_t size = 0;
  size_t read = 0;
  zip_error_t error;

  bool Make() {
    if (made) return true;
    Status st = make(&bytes);
    if (!st.ok()) {
      if (first_error->ok()) *first_error = st;
      zip_error_set(&error, ZIP_ER_INTERNAL, 0);
      return false;
    }
    made = true;
    return true;
  }
};

zip_int64_t LazyEntryCallback(void* user, void* data, zip_uint64_t len, zip_source_cmd_t cmd) {
  auto* e = static_cast<LazyEntry*>(user);
  switch (cmd) {
    case ZIP_SOURCE_OPEN:
      e->read = 0;
      return e->Make() ? 0 : -1;
    case ZIP_SOURCE_READ: {
      const size_t n = std::min<size_t>(len, e->bytes.size() - e->read);
      if (n) std::memcpy(data, e->bytes.data() + e->read, n);
      e->read += n;
      return static_cast<zip_int64_t>(n);
    }
    case ZIP_SOURCE_CLOSE:
      std::vector<uint8_t>().swap(e->bytes);
      e->made = false;
      return 0;
    case ZIP_SOURCE_STAT: {
      // libzip asks again after the entry is written: answer from the size kept, not by making it anew.
      if (!e->size_known) {
        if (!e->Make()) return -1;
        e->size = e->bytes.size();
        e->size_known = true;
      }
      auto* st = static_cast<zip_stat_t*>(data);
      zip_stat_init(st);
      st->size = e->size;
      st->valid |= ZIP_STAT_SIZE;
      return sizeof(*st);
    }
    case ZIP_SOURCE_ERROR:
      return zip_error_to_data(&e->error, data, len);
    case ZIP_SOURCE_FREE:
      zip_error_fini(&e->error);
      delete e;
      return 0;
    case ZIP_SOURCE_SUPPORTS:
      return zip_source_make_command_bitmap(ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE,
                                            ZIP_SOURCE_STAT, ZIP_SOURCE_ERROR, ZIP_SOURCE_FREE, -1);
    default:
      zip_error_set(&e->error, ZIP_ER_OPNOTSUPP, 0);
      return -1;
  }
}

// The archive being written: libzip on a temporary file beside the target.
class BcfArchive {
 public:
  BcfArchive(std::string path, int64_t mtime) : path_(std::move(path)), temp_(AtomicTempPath(path_)) {
    const time_t t = static_cast<time_t>(mtime);
    struct tm tm {};
    localtime_r(&t, &tm);  // libzip keeps DOS times in local time
    dos_date_ =
        static_cast<uint16_t>((std::max(tm.tm_year, 80) - 80) << 9 | (tm.tm_mon + 1) << 5 | tm.tm_mday);
    dos_time_ = static_cast<uint16_t>(tm.tm_hour << 11 | tm.tm_min << 5 | tm.tm_sec / 2);
  }
  ~BcfArchive() {
    if (zip_) zip_discard(zip_);
    if (!committed_) ::unlink(temp_.c_str());
    if (lock_fd_ >= 0) ::close(lock_fd_);
  }

  Status Open() {
    RemoveStaleTemps(path_);
    // Held with a flock while the archive is written, so that another writer's RemoveStaleTemps leaves it.
    lock_fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (lock_fd_ < 0) return Status::IOError(path_ + ": cannot create file: " + std::strerror(errno));
    ::flock(lock_fd_, LOCK_EX | LOCK_NB);
    int err = 0;
    zip_ = zip_open(temp_.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
    if (!zip_) {
      zip_error_t ze;
      zip_error_init_with_code(&ze, err);
      Status st = Status::IOError(path_ + ": cannot start the archive: " + zip_error_strerror(&ze));
      zip_error_fini(&ze);
      return st;
    }
    return Status::Ok();
  }

  // Adds `name`, made at the end by `make`; stored as is (`store`, for PNG) or deflated.
  Status Add(const std::string& name, std::function<Status(std::vector<uint8_t>*)> make, bool store = false) {
    auto* e = new LazyEntry{std::move(make), &first_error_, {}, false, false, 0, 0, {}};
    zip_error_init(&e->error);
    zip_source_t* src = zip_source_function(zip_, LazyEntryCallback, e);
    if (!src) {
      zip_error_fini(&e->error);
      delete e;
      return Error("cannot add " + name);
    }
    const zip_int64_t i = zip_file_add(zip_, name.c_str(), src, ZIP_FL_ENC_UTF_8);
    if (i < 0) {
      zip_source_free(src);
      return Error("cannot add " + name);
    }
    const auto idx = static_cast<zip_uint64_t>(i);
    if (zip_set_file_compression(zip_, idx, store ? ZIP_CM_STORE : ZIP_CM_DEFLATE, 9) < 0 ||
        zip_file_set_dostime(zip_, idx, dos_time_, dos_date_, 0) < 0)
      return Error("cannot set up " + name);
    return Status::Ok();
  }
  Status AddText(const std::string& name, std::function<std::string()> make) {
    return Add(name, [make = std::move(make)](std::vector<uint8_t>* out) {
      const std::string s = make();
      out->assign(s.begin(), s.end());
      return Status::Ok();
    });
  }

  // Writes the archive (every entry made now), makes it durable and renames it over the target.
  Result<uint64_t> Commit() {
    if (zip_close(zip_) < 0) {
      Status st = first_error_.ok() ? Error("cannot write the archive") : first_error_;
      return st;
    }
    zip_ = nullptr;
    const int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0 || ::fsync(fd) != 0) {
      const int e = errno;
      if (fd >= 0) ::close(fd);
      return Status::IOError(path_ + ": fsync: " + std::strerror(e));
    }
    struct stat sb {};
    ::fstat(fd, &sb);
    ::close(fd);
    bool renamed = false;
    MKTREE_RETURN_IF_ERROR(RenameOverTarget(temp_, path_, DefaultFileOps(), "the BCF archive", &renamed));
    committed_ = renamed;
    return static_cast<uint64_t>(sb.st_size);
  }

 private:
  Status Error(const std::string& what) const {
    return Status::IOError(path_ + ": " + what + ": " + (zip_ ? zip_strerror(zip_) : ""));
  }

  std::string path_, temp_;
  zip_t* zip_ = nullptr;
  int lock_fd_ = -1;
  bool committed_ = false;
  Status first_error_;
  uint16_t dos_date_ = 0, dos_time_ = 0;
};

}  // namespace

Result<BcfWriteReport> WriteBcf(const ClashRun& run, const std::string& path, const BcfOptions& options) {
  BcfOptions o = options;
  if (Blank(o.author)) o.author = "mktree";
  if (Blank(o.open_status)) o.open_status = "Open";
  if (Blank(o.closed_status)) o.closed_status = "Closed";
  if (o.creation_time < 0) {  // SOURCE_DATE_EPOCH: the reproducible-builds convention for a fixed time
    const char* epoch = std::getenv("SOURCE_DATE_EPOCH");
    o.creation_time =
        epoch && *epoch ? std::strtoll(epoch, nullptr, 10) : static_cast<int64_t>(std::time(nullptr));
  }
  std::set<std::string> keys;
  for (size_t i = 0; i < run.groups.size(); ++i) {
    if (run.groups[i].key.empty())
      return Status::InvalidArgument(path + ": group " + std::to_string(i + 1) + " has no key");
    if (!keys.insert(run.groups[i].key).second)
      return Status::InvalidArgument(path + ": two groups have the key '" + run.groups[i].key +
                                     "': their topics would share a GUID");
  }
  BcfArchive zip(path, o.creation_time);
  MKTREE_RETURN_IF_ERROR(zip.Open());
  MKTREE_RETURN_IF_ERROR(zip.AddText("bcf.version", [&o] { return VersionXml(o.version); }));
  MKTREE_RETURN_IF_ERROR(zip.AddText("project.bcfp", [&run, &o] { return ProjectXml(run, o); }));
  if (o.version == BcfVersion::k3_0)
    MKTREE_RETURN_IF_ERROR(zip.AddText("extensions.xml", [&run, &o] { return ExtensionsXml(run, o); }));
  BcfWriteReport report;
  for (size_t i = 0; i < run.groups.size(); ++i) {
    const ClashGroup& g = run.groups[i];
    const bool snapshot = o.snapshot && i < o.max_snapshots;
    // The topic's XML files are made from the group when libzip writes them, so that no topic is held.
    const BcfTopic topic = BcfTopicOf(g, o, snapshot);
    const std::string dir = topic.guid + "/";
    MKTREE_RETURN_IF_ERROR(zip.AddText(
        dir + "markup.bcf", [&g, &o, snapshot] { return MarkupXml(BcfTopicOf(g, o, snapshot), o.version); }));
    MKTREE_RETURN_IF_ERROR(zip.AddText(dir + topic.viewpoints[0].file, [&g, &o, snapshot] {
      return ViewpointXml(BcfTopicOf(g, o, snapshot).viewpoints[0], o.version);
    }));
    if (snapshot) {
      MKTREE_RETURN_IF_ERROR(zip.Add(
          dir + "snapshot.png",
          [&o, &g](std::vector<uint8_t>* out) -> Status {
            auto png = o.snapshot(g);
            if (!png.ok()) return png.status();
            *out = std::move(*png);
            return Status::Ok();
          },
          /*store=*/true));
      ++report.snapshots;
    }
    ++report.topics;
    report.components += topic.viewpoints[0].selected.size();
  }
  MKTREE_ASSIGN_OR_RETURN(report.bytes, zip.Commit());
  return report;
}

}  // namespace mktree
