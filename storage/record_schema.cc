#include "storage/record_schema.h"

#include <cstdlib>
#include <cstring>

#include "storage/byte_io.h"  // the little-endian host check: the encoding is the in-RAM bytes

namespace mktree {

const RecordField& RecordSchema::field(std::string_view name) const {
  for (const RecordField& f : fields)
    if (f.name != nullptr && name == f.name) return f;
  std::abort();
}

void EncodeRecords(const RecordSchema& s, const void* records, size_t n, std::vector<uint8_t>* out) {
  const size_t each = s.encoded_bytes(), at = out->size();
  out->resize(at + n * each, 0);  // reserved fields stay zero
  const auto* in = static_cast<const uint8_t*>(records);
  uint8_t* p = out->data() + at;
  for (size_t i = 0; i < n; ++i, in += s.ram_bytes) {
    for (const RecordField& f : s.fields) {
      if (f.name != nullptr) std::memcpy(p, in + f.offset, f.bytes());
      p += f.bytes();
    }
  }
}

Status DecodeRecords(const RecordSchema& s, std::span<const uint8_t> in, void* records) {
  const size_t each = s.encoded_bytes();
  if (in.size() % each != 0)
    return Status::Corruption(std::string(s.what) + " section size " + std::to_string(in.size()) +
                              " is not a multiple of its record size " + std::to_string(each));
  auto* out = static_cast<uint8_t*>(records);
  const uint8_t* p = in.data();
  for (size_t i = 0; i < in.size() / each; ++i, out += s.ram_bytes) {
    for (const RecordField& f : s.fields) {
      if (f.name != nullptr) {
        if (!f.labels.empty() && *p >= f.labels.size())
          return Status::Corruption(std::string(s.what) + " " + f.name + " out of range");
        std::memcpy(out + f.offset, p, f.bytes());
      }
      p += f.bytes();
    }
  }
  return Status::Ok();
}

}  // namespace mktree
