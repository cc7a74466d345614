// Fuzz target: the queries-file parser of `mktree query --queries FILE` (tools/query_file.h), and the
// --point/--box argument parsers on the same bytes. Accepted queries must be finite, boxes ordered.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_util.h"
#include "tools/query_file.h"

namespace {

void Check(const mktree::Query& q) {
  for (int i = 0; i < 3; ++i) {
    const double lo = q.kind == mktree::Query::Kind::kPoint ? q.point[i] : q.box.min[i];
    const double hi = q.kind == mktree::Query::Kind::kPoint ? q.point[i] : q.box.max[i];
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = mktree::fuzz::InputFile::Get().Write(data, size);
  auto queries = mktree::tools::ReadQueryFile(path);
  if (queries.ok()) {
    for (const mktree::Query& q : *queries) Check(q);
    ++mktree::fuzz::g_accepted;
  } else {
    mktree::fuzz::Refused(queries.status().ToString());
  }
  const std::string text(reinterpret_cast<const char*>(data), size);
  if (auto p = mktree::tools::ParsePointArg(text); p.ok()) Check(*p);
  if (auto b = mktree::tools::ParseBoxArg(text); b.ok()) Check(*b);
  return 0;
}
