#include "engine/generator/tanker_spec.h"

#include <charconv>
#include <system_error>

namespace mktree {

namespace {

std::optional<uint64_t> Decimal(std::string_view text) {
  uint64_t v = 0;
  if (text.empty() || text[0] < '0' || text[0] > '9') return std::nullopt;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return v;
}

}  // namespace

bool IsTankerSpec(std::string_view input) { return input.substr(0, 7) == "tanker:"; }

std::optional<TankerSpec> ParseTankerSpec(std::string_view input) {
  if (!IsTankerSpec(input)) return std::nullopt;
  const std::string_view spec = input.substr(7);
  const size_t colon = spec.find(':');
  const std::optional<uint64_t> n = Decimal(spec.substr(0, colon));
  const std::optional<uint64_t> seed =
      colon == std::string_view::npos ? std::optional<uint64_t>(1) : Decimal(spec.substr(colon + 1));
  if (!n || !seed || *n == 0 || *n > (uint64_t{1} << 32)) return std::nullopt;
  return TankerSpec{*n, *seed};
}

}  // namespace mktree
