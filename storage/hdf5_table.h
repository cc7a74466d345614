// Tables of records in HDF5: a 1-D dataset whose element type is generated from a record schema
// (storage/record_schema.h), written from and read straight into the in-RAM records. Every length read
// from a file is bounded before anything is allocated for it, so a damaged or crafted dataspace cannot
// make a reader allocate more than the file could hold.
// Thread safety: hold an hdf5::Lock around every call.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mktree/status.h"
#include "storage/hdf5_file.h"
#include "storage/record_schema.h"

namespace mktree::hdf5 {

// The HDF5 type of one field: its scalar type, an enumeration of its labels, an array for count > 1.
// `file`: little-endian, as stored; otherwise native, as in memory.
H5Id FieldH5Type(const RecordField& f, bool file);
// The HDF5 type of a record. A compound of the schema's named fields in schema order: as stored (`file`),
// packed back to back; in memory, at the fields' offsets in a record of ram_bytes. Reserved fields are
// left out. A column's type is its field's.
H5Id RecordH5Type(const RecordSchema& s, bool file);

struct TableLayout {
  uint64_t chunk_rows = 0;  // 0: contiguous; else chunks of at most this many rows
  int deflate = -1;         // chunked only: the deflate level, or -1 for none
  bool shuffle = false;     // chunked only: HDF5's shuffle filter (before deflate)
};

// Creates the 1-D dataset `name` in `loc` and writes `records` (Records<Schema>(vector)) to it; returns the
// dataset, open. Errors: IOError "<path>: writing <shown>: <HDF5's message>" (`shown` defaults to name).
Result<H5Id> WriteTable(hid_t loc, const char* name, const RecordsView& records, const std::string& path,
                        const TableLayout& layout = {}, std::string_view shown = {});

// The length of the 1-D dataset `d` (called `name` in errors), refused as Corruption unless its elements,
// at their size in the file, fit in `max_bytes`.
Result<hsize_t> TableLength(hid_t d, const char* name, uint64_t max_bytes, const std::string& path);
// Reads every row of the open dataset `d` as records of schema `s` into `records` (room for all of them).
// Errors: Corruption "<path>: reading <shown>: <HDF5's message>".
Status ReadRows(hid_t d, const RecordSchema& s, void* records, const std::string& path,
                std::string_view shown);
// The same into a container of S's records (vector, string) already sized to the dataset's length.
template <const RecordSchema& S, typename Container>
Status ReadRows(hid_t d, Container* records, const std::string& path, std::string_view shown) {
  static_assert(sizeof(*std::data(*records)) == S.ram_bytes, "the schema describes another record");
  return ReadRows(d, S, std::data(*records), path, shown);
}

// Opens the 1-D dataset `name` of `loc` and bounds its length by `max_bytes` (TableLength). Corruption if
// it is missing or does not open.
Status OpenTable(hid_t loc, const char* name, uint64_t max_bytes, const std::string& path, H5Id* d,
                 hsize_t* rows);

// Reads the 1-D dataset `name` of `loc` into `out`, resized to its length once that is bounded by
// `max_bytes`. S is the schema of T.
template <const RecordSchema& S, typename T>
Status ReadTable(hid_t loc, const char* name, std::vector<T>* out, uint64_t max_bytes,
                 const std::string& path) {
  H5Id d;
  hsize_t n = 0;
  MKTREE_RETURN_IF_ERROR(OpenTable(loc, name, max_bytes, path, &d, &n));
  out->resize(n);
  return n > 0 ? ReadRows<S>(d.get(), out, path, name) : Status::Ok();
}

}  // namespace mktree::hdf5
