#include "engine/report/bcf_reader.h"

#include <zip.h>

#include <cstdlib>
#include <memory>

#include "engine/report/xml_element.h"

namespace mktree {

namespace {

using ZipHandle = std::unique_ptr<zip_t, void (*)(zip_t*)>;

// The whole entry `name`, or NotFound.
Result<std::string> ReadEntry(zip_t* z, const std::string& path, const std::string& name) {
  zip_stat_t st;
  if (zip_stat(z, name.c_str(), 0, &st) < 0) return Status::NotFound(path + ": no entry " + name);
  zip_file_t* f = zip_fopen(z, name.c_str(), 0);
  if (!f) return Status::IOError(path + ": " + name + ": " + zip_strerror(z));
  std::string bytes(st.size, '\0');
  const zip_int64_t n = zip_fread(f, bytes.data(), st.size);
  zip_fclose(f);
  if (n < 0 || static_cast<zip_uint64_t>(n) != st.size)
    return Status::IOError(path + ": " + name + ": cannot read the entry");
  return bytes;
}

Result<XmlElement> ReadXmlEntry(zip_t* z, const std::string& path, const std::string& name) {
  auto bytes = ReadEntry(z, path, name);
  if (!bytes.ok()) return bytes.status();
  return ParseXml(*bytes, path + ": " + name);
}

Vec3d ReadPoint(const XmlElement* e) {
  if (!e) return {};
  return {std::atof(e->ChildText("X").c_str()), std::atof(e->ChildText("Y").c_str()),
          std::atof(e->ChildText("Z").c_str())};
}

void ReadComponents(const XmlElement* parent, std::vector<std::string>* out) {
  if (!parent) return;
  for (const XmlElement& c : parent->children) {
    if (c.name != "Component") continue;
    std::string id = c.Attribute("IfcGuid");
    if (id.empty()) id = c.ChildText("AuthoringToolId");
    out->push_back(id);
  }
}

Status ReadViewpoint(zip_t* z, const std::string& path, const std::string& dir, BcfViewpoint* v) {
  auto x = ReadXmlEntry(z, path, dir + v->file);
  if (!x.ok()) return x.status();
  if (x->name != "VisualizationInfo")
    return Status::InvalidArgument(path + ": " + dir + v->file + ": not a VisualizationInfo");
  if (v->guid.empty()) v->guid = x->Attribute("Guid");
  if (const XmlElement* comps = x->Child("Components")) {
    ReadComponents(comps->Child("Selection"), &v->selected);
    if (const XmlElement* col = comps->Child("Coloring")) {
      for (const XmlElement& c : col->children) {
        if (c.name != "Color") continue;
        BcfColouring colouring{c.Attribute("Color"), {}};
        const XmlElement* list = c.Child("Components");  // 3.0 wraps them
        ReadComponents(list ? list : &c, &colouring.components);
        v->colours.push_back(std::move(colouring));
      }
    }
  }
  if (const XmlElement* cam = x->Child("PerspectiveCamera")) {
    v->camera.position = ReadPoint(cam->Child("CameraViewPoint"));
    v->camera.direction = ReadPoint(cam->Child("CameraDirection"));
    v->camera.up = ReadPoint(cam->Child("CameraUpVector"));
    v->camera.field_of_view = std::atof(cam->ChildText("FieldOfView").c_str());
    const std::string aspect = cam->ChildText("AspectRatio");
    v->camera.aspect_ratio = aspect.empty() ? 1.0 : std::atof(aspect.c_str());
  }
  if (!v->snapshot_file.empty()) {
    zip_stat_t st;
    v->has_snapshot = zip_stat(z, (dir + v->snapshot_file).c_str(), 0, &st) == 0;
  }
  return Status::Ok();
}

BcfViewpoint ViewpointReference(const XmlElement& e) {
  BcfViewpoint v;
  v.guid = e.Attribute("Guid");
  v.file = e.ChildText("Viewpoint");
  v.snapshot_file = e.ChildText("Snapshot");
  return v;
}

Status ReadTopic(zip_t* z, const std::string& path, const std::string& markup_name, BcfTopic* t) {
  auto x = ReadXmlEntry(z, path, markup_name);
  if (!x.ok()) return x.status();
  const XmlElement* topic = x->Child("Topic");
  if (x->name != "Markup" || !topic) return Status::InvalidArgument(path + ": " + markup_name + ": no Topic");
  t->guid = topic->Attribute("Guid");
  t->type = topic->Attribute("TopicType");
  t->status = topic->Attribute("TopicStatus");
  t->title = topic->ChildText("Title");
  t->creation_date = topic->ChildText("CreationDate");
  t->author = topic->ChildText("CreationAuthor");
  if (const XmlElement* d = topic->Child("Description")) t->description = d->text;  // as written
  for (const XmlElement& c : topic->children) {
    if (c.name != "Labels") continue;
    if (c.children.empty() && !c.text.empty()) t->labels.push_back(c.text);  // 2.1: one element a label
    for (const XmlElement& l : c.children)
      if (l.name == "Label") t->labels.push_back(l.text);  // 3.0
  }
  if (const XmlElement* h = x->Child("Header")) {
    const XmlElement* files = h->Child("Files");  // 3.0 wraps them
    for (const XmlElement& f : (files ? files : h)->children)
      if (f.name == "File") t->files.push_back(f.ChildText("Filename"));
  }
  for (const XmlElement& c : x->children)  // 2.1: Markup/Viewpoints, one per viewpoint
    if (c.name == "Viewpoints") t->viewpoints.push_back(ViewpointReference(c));
  if (const XmlElement* vps = topic->Child("Viewpoints"))  // 3.0: Topic/Viewpoints/ViewPoint
    for (const XmlElement& c : vps->children)
      if (c.name == "ViewPoint") t->viewpoints.push_back(ViewpointReference(c));
  const std::string dir = markup_name.substr(0, markup_name.size() - std::string("markup.bcf").size());
  for (BcfViewpoint& v : t->viewpoints) {
    if (v.file.empty()) continue;
    MKTREE_RETURN_IF_ERROR(ReadViewpoint(z, path, dir, &v));
  }
  return Status::Ok();
}

}  // namespace

Result<BcfArchiveContents> ReadBcf(const std::string& path) {
  int err = 0;
  ZipHandle z(zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &err), zip_discard);
  if (!z) {
    zip_error_t ze;
    zip_error_init_with_code(&ze, err);
    Status st = Status::InvalidArgument(path + ": not a BCF archive (zip): " + zip_error_strerror(&ze));
    zip_error_fini(&ze);
    return st;
  }
  BcfArchiveContents out;
  auto version = ReadXmlEntry(z.get(), path, "bcf.version");
  if (!version.ok()) return version.status();
  out.version = version->Attribute("VersionId");
  if (out.version != "2.0" && out.version != "2.1" && out.version != "3.0")
    return Status::InvalidArgument(path + ": bcf.version: unknown BCF version '" + out.version + "'");
  auto project = ReadXmlEntry(z.get(), path, "project.bcfp");
  if (project.ok()) {
    if (const XmlElement* p = project->Child("Project")) out.project_name = p->ChildText("Name");
  } else if (project.status().code() != Status::Code::kNotFound) {
    return project.status();
  }
  const zip_int64_t n = zip_get_num_entries(z.get(), 0);
  for (zip_int64_t i = 0; i < n; ++i) {
    const char* name = zip_get_name(z.get(), static_cast<zip_uint64_t>(i), 0);
    if (!name) continue;
    const std::string s = name;
    const size_t slash = s.find('/');
    if (slash == std::string::npos || s.substr(slash + 1) != "markup.bcf") continue;
    BcfTopic t;
    MKTREE_RETURN_IF_ERROR(ReadTopic(z.get(), path, s, &t));
    out.topics.push_back(std::move(t));
  }
  return out;
}

}  // namespace mktree
