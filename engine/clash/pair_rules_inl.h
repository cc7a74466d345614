// Exclusions::BuildGroups (a template over how names are fetched).
#pragma once

#include <string_view>
#include <unordered_map>

#include "engine/clash/pair_rules.h"

namespace mktree::clash {

template <typename NameOf>
void Exclusions::BuildGroups(const std::string& sep, uint64_t count, NameOf& name) {
  group_.assign(count, kNoGroup);
  std::unordered_map<std::string, uint32_t> ids;
  for (uint64_t i = 0; i < count; ++i) {
    const std::string_view n = name(i);
    const size_t at = n.find(sep);
    if (at == std::string_view::npos) continue;
    auto [it, added] = ids.try_emplace(std::string(n.substr(0, at)), static_cast<uint32_t>(ids.size()));
    group_[i] = it->second;
  }
}

}  // namespace mktree::clash
