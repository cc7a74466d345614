#include "storage/hdf5_table.h"

#include <algorithm>

namespace mktree::hdf5 {

H5Id FieldH5Type(const RecordField& f, bool file) {
  const hid_t base = ScalarType(f.type, file);
  H5Id element;
  if (f.labels.empty()) {
    element = H5Id(H5Tcopy(base), H5Tclose);
  } else {
    element = H5Id(H5Tenum_create(base), H5Tclose);
    for (uint8_t v = 0; v < f.labels.size(); ++v) H5Tenum_insert(element.get(), f.labels[v], &v);
  }
  if (f.count == 1) return element;
  const hsize_t n = f.count;
  return H5Id(H5Tarray_create2(element.get(), 1, &n), H5Tclose);
}

H5Id RecordH5Type(const RecordSchema& s, bool file) {
  if (!s.compound) return FieldH5Type(s.fields[0], file);
  std::vector<H5Id> members;
  std::vector<const RecordField*> named;
  size_t packed = 0;
  for (const RecordField& f : s.fields) {
    if (f.name == nullptr) continue;
    members.push_back(FieldH5Type(f, file));
    named.push_back(&f);
    packed += H5Tget_size(members.back().get());
  }
  H5Id t(H5Tcreate(H5T_COMPOUND, file ? packed : s.ram_bytes), H5Tclose);
  size_t at = 0;
  for (size_t i = 0; i < members.size(); ++i) {
    H5Tinsert(t.get(), named[i]->name, file ? at : named[i]->offset, members[i].get());
    at += H5Tget_size(members[i].get());
  }
  return t;
}

Result<H5Id> WriteTable(hid_t loc, const char* name, const RecordsView& records, const std::string& path,
                        const TableLayout& layout, std::string_view shown) {
  const RecordSchema& s = *records.schema;
  const uint64_t n = records.count;
  const hsize_t dims[1] = {n};
  H5Id space(H5Screate_simple(1, dims, nullptr), H5Sclose);
  H5Id dcpl;
  if (layout.chunk_rows > 0 && n > 0) {
    const hsize_t chunk[1] = {std::min<hsize_t>(n, layout.chunk_rows)};
    dcpl = H5Id(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    H5Pset_chunk(dcpl.get(), 1, chunk);
    if (layout.shuffle) H5Pset_shuffle(dcpl.get());
    if (layout.deflate >= 0) H5Pset_deflate(dcpl.get(), static_cast<unsigned>(layout.deflate));
  }
  const H5Id file_type = RecordH5Type(s, true), mem_type = RecordH5Type(s, false);
  H5Id d(H5Dcreate2(loc, name, file_type.get(), space.get(), H5P_DEFAULT,
                    dcpl.ok() ? dcpl.get() : H5P_DEFAULT, H5P_DEFAULT),
         H5Dclose);
  if (!d.ok() ||
      (n > 0 && H5Dwrite(d.get(), mem_type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, records.data) < 0))
    return Status::IOError(path + ": writing " + std::string(shown.empty() ? name : shown) + ": " +
                           ErrorText());
  return d;
}

Result<hsize_t> TableLength(hid_t d, const char* name, uint64_t max_bytes, const std::string& path) {
  H5Id space(H5Dget_space(d), H5Sclose);
  H5Id type(H5Dget_type(d), H5Tclose);
  hsize_t dims[1] = {0};
  if (!space.ok() || H5Sget_simple_extent_ndims(space.get()) != 1 ||
      H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0)
    return Status::Corruption(path + ": dataset " + name + " is not 1-D");
  const size_t each = type.ok() ? H5Tget_size(type.get()) : 0;
  if (each == 0) return Status::Corruption(path + ": dataset " + name + " has no valid type");
  if (dims[0] > max_bytes / each)
    return Status::Corruption(path + ": dataset " + name + " claims " + std::to_string(dims[0]) +
                              " elements of " + std::to_string(each) + " bytes, more than the file's " +
                              std::to_string(max_bytes) + " bytes hold");
  return dims[0];
}

Status ReadRows(hid_t d, const RecordSchema& s, void* records, const std::string& path,
                std::string_view shown) {
  const H5Id mem_type = RecordH5Type(s, false);
  if (H5Dread(d, mem_type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, records) < 0)
    return Status::Corruption(path + ": reading " + std::string(shown) + ": " + ErrorText());
  return Status::Ok();
}

Status OpenTable(hid_t loc, const char* name, uint64_t max_bytes, const std::string& path, H5Id* d,
                 hsize_t* rows) {
  if (H5Lexists(loc, name, H5P_DEFAULT) <= 0) return Status::Corruption(path + ": missing dataset " + name);
  *d = H5Id(H5Dopen2(loc, name, H5P_DEFAULT), H5Dclose);
  if (!d->ok()) return Status::Corruption(path + ": dataset " + name + ": " + ErrorText());
  auto n = TableLength(d->get(), name, max_bytes, path);
  if (!n.ok()) return n.status();
  *rows = *n;
  return Status::Ok();
}

}  // namespace mktree::hdf5
