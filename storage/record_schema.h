// RecordSchema: the fields of a fixed-width on-disk record, each named, typed and located in the in-RAM
// struct it is stored from. One schema drives both encodings of a table of such records, so that they
// cannot drift apart:
//   - the canonical byte encoding (EncodeRecords/DecodeRecords): the fields back to back, little-endian,
//     reserved fields as zeros. The paged file stores these bytes as sections and both backends checksum
//     them;
//   - the HDF5 types (storage/hdf5_table.h): a compound of the named fields in schema order, each of its
//     little-endian type (arrays for count > 1, enumerations for labelled fields), reserved fields left
//     out; in memory, the same fields at their offsets in the struct, so HDF5 reads straight into it.
// A column schema (compound = false) has one field: a plain array of that type (HDF5: not a compound).
// Thread safety: schemas are constants; the functions are pure.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iterator>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "mktree/status.h"

namespace mktree {

enum class FieldType : uint8_t { kU8, kU16, kU32, kU64, kI32, kF32, kF64 };

constexpr size_t FieldTypeBytes(FieldType t) {
  switch (t) {
    case FieldType::kU8:
      return 1;
    case FieldType::kU16:
      return 2;
    case FieldType::kU32:
    case FieldType::kI32:
    case FieldType::kF32:
      return 4;
    case FieldType::kU64:
    case FieldType::kF64:
      return 8;
  }
  return 0;
}

// The field type of a C++ scalar.
template <typename T>
constexpr FieldType FieldTypeOf() {
  if constexpr (std::is_same_v<T, uint8_t>)
    return FieldType::kU8;
  else if constexpr (std::is_same_v<T, uint16_t>)
    return FieldType::kU16;
  else if constexpr (std::is_same_v<T, uint32_t>)
    return FieldType::kU32;
  else if constexpr (std::is_same_v<T, uint64_t>)
    return FieldType::kU64;
  else if constexpr (std::is_same_v<T, int32_t>)
    return FieldType::kI32;
  else if constexpr (std::is_same_v<T, float>)
    return FieldType::kF32;
  else if constexpr (std::is_same_v<T, double>)
    return FieldType::kF64;
  else
    static_assert(sizeof(T) == 0, "no field type for this C++ type");
}

struct RecordField {
  const char* name;  // nullptr: reserved bytes (zeros when encoded, skipped when decoded, absent in HDF5)
  size_t offset;     // of the member in the in-RAM record
  FieldType type;    // of each element
  uint32_t count;    // elements (> 1: an array, such as a box corner's three floats)
  // An enumeration: value i is named labels[i]; a larger value does not decode.
  std::span<const char* const> labels = {};

  constexpr size_t bytes() const { return FieldTypeBytes(type) * count; }
};

struct RecordSchema {
  const char* what;  // the record's name in errors ("node")
  size_t ram_bytes;  // sizeof the in-RAM record
  std::span<const RecordField> fields;
  bool compound = true;  // false: a column, one field stored as a plain array of its type

  constexpr size_t encoded_bytes() const {
    size_t n = 0;
    for (const RecordField& f : fields) n += f.bytes();
    return n;
  }
  // The field called `name`. REQUIRES: there is one (aborts otherwise: a misspelt name is a bug).
  const RecordField& field(std::string_view name) const;
};

// A field for the member of `member_bytes` bytes at `offset` of its record (use MKTREE_RECORD_FIELD).
// Fails to compile unless the member is a whole number of elements of `type`.
consteval RecordField MakeRecordField(const char* name, size_t offset, size_t member_bytes, FieldType type,
                                      std::span<const char* const> labels = {}) {
  if (member_bytes == 0 || member_bytes % FieldTypeBytes(type) != 0)
    throw "the member's size is not a whole number of elements of the field's type";
  if (!labels.empty() && (type != FieldType::kU8 || member_bytes != 1))
    throw "labelled fields are single bytes";
  return {name, offset, type, static_cast<uint32_t>(member_bytes / FieldTypeBytes(type)), labels};
}
consteval RecordField ReservedField(FieldType type) { return {nullptr, 0, type, 1}; }

// Checks at compile time that the named fields lie within the record and do not overlap.
consteval bool FieldsFitRecord(const RecordSchema& s) {
  for (size_t i = 0; i < s.fields.size(); ++i) {
    const RecordField& a = s.fields[i];
    if (a.name == nullptr) continue;
    if (a.offset + a.bytes() > s.ram_bytes) return false;
    for (size_t j = i + 1; j < s.fields.size(); ++j) {
      const RecordField& b = s.fields[j];
      if (b.name != nullptr && a.offset < b.offset + b.bytes() && b.offset < a.offset + a.bytes())
        return false;
    }
  }
  return !s.fields.empty() && (s.compound || s.fields.size() == 1);
}

// MKTREE_RECORD_FIELD("box_min", TreeNode, box.min, kF32): the field "box_min" of TreeNode, its member
// box.min, an array of float32 as long as the member.
#define MKTREE_RECORD_FIELD(name, Record, member, type, ...)                                        \
  ::mktree::MakeRecordField(name, offsetof(Record, member), sizeof(std::declval<Record&>().member), \
                            ::mktree::FieldType::type __VA_OPT__(, ) __VA_ARGS__)

// A column of bytes (names, opaque blobs).
inline constexpr RecordField kByteFields[] = {MakeRecordField("byte", 0, 1, FieldType::kU8)};
inline constexpr RecordSchema kByteColumn{"byte", 1, kByteFields, false};

// Appends the canonical encoding of `n` records, ram_bytes apart from `records`, to `out`.
void EncodeRecords(const RecordSchema& s, const void* records, size_t n, std::vector<uint8_t>* out);
// Decodes in.size() / encoded_bytes() records into `records` (room for that many, constructed: reserved
// bytes and members outside the schema are left as they are). Corruption if `in` is not a whole number of
// records ("<what> section size N is not a multiple of its record size R") or a labelled field holds a
// value without a label ("<what> <field> out of range").
Status DecodeRecords(const RecordSchema& s, std::span<const uint8_t> in, void* records);

// Typed forms: S is the schema of T.
template <const RecordSchema& S, typename T>
std::vector<uint8_t> EncodeRecords(std::span<const T> records) {
  static_assert(sizeof(T) == S.ram_bytes, "the schema describes another record");
  std::vector<uint8_t> out;
  EncodeRecords(S, records.data(), records.size(), &out);
  return out;
}
template <const RecordSchema& S, typename T>
Status DecodeRecords(std::span<const uint8_t> in, std::vector<T>* out) {
  static_assert(sizeof(T) == S.ram_bytes, "the schema describes another record");
  const size_t each = S.encoded_bytes();
  out->assign(in.size() % each == 0 ? in.size() / each : 0, T{});
  return DecodeRecords(S, in, out->data());
}

// In-RAM records of a schema, as the type-erased functions take them (storage/hdf5_table.h).
struct RecordsView {
  const RecordSchema* schema;
  const void* data;
  uint64_t count;
};
// The records of a contiguous container (vector, string, span) of S's record type.
template <const RecordSchema& S, typename Container>
RecordsView Records(const Container& c) {
  static_assert(sizeof(*std::data(c)) == S.ram_bytes, "the schema describes another record");
  return {&S, std::data(c), std::size(c)};
}

}  // namespace mktree
