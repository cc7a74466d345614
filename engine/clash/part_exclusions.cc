#include "engine/clash/part_exclusions.h"

#include <functional>
#include <memory>
#include <queue>
#include <string_view>
#include <utility>
#include <vector>

#include "engine/store_format/record_codec.h"

namespace mktree::clash {

Status MakePartExclusions(const PartNumbering& parts, const ClashOptions& o, std::optional<Exclusions>* out) {
  const size_t np = parts.part_count();
  // Global ids come in increasing order: the parts' next ids in a heap (ids increase within a part).
  Status names_status;
  std::vector<std::unique_ptr<RecordReader>> names;
  for (size_t k = 0; k < np; ++k)
    names.push_back(std::make_unique<RecordReader>(parts.store(k).reader().record_layout(), nullptr,
                                                   parts.store(k).verify_checksums()));
  std::vector<uint64_t> cursor(np, 0);
  using Head = std::pair<uint64_t, size_t>;  // (global id, part)
  std::priority_queue<Head, std::vector<Head>, std::greater<Head>> heads;
  // Hidden objects are skipped: their global ids may repeat a visible object's of another part.
  auto push_next_visible = [&](size_t k) {
    while (cursor[k] < parts.object_count(k) && parts.hidden(k, static_cast<ObjectId>(cursor[k])))
      ++cursor[k];
    if (cursor[k] < parts.object_count(k))
      heads.push({parts.global_id(k, static_cast<ObjectId>(cursor[k])), k});
  };
  if (!o.exclude_group_separator.empty())
    for (size_t k = 0; k < np; ++k) push_next_visible(k);
  out->emplace(o, parts.global_count(), [&](uint64_t g) -> std::string_view {
    if (!names_status.ok() || heads.empty() || heads.top().first != g) return {};
    const size_t k = heads.top().second;
    heads.pop();
    const uint64_t at = cursor[k]++;
    push_next_visible(k);
    auto r = names[k]->Get(static_cast<uint32_t>(at), nullptr);
    if (!r.ok()) names_status = r.status();
    return r.ok() ? std::string_view((*r)->name) : std::string_view();
  });
  return names_status;
}

}  // namespace mktree::clash
