// Numbers on the command line, parsed strictly: CLI11 converts with strtoull/strtoll in base 0, so "-1"
// wraps to 2^64 - 1 for a 64-bit unsigned option, "99999999999999999999" saturates, "010" is octal and ""
// is 0. Here a number is decimal and the whole text: anything else is a usage error (exit 2, docs/cli.md),
// raised while the command line is parsed. Range checks (--count > 0, --level >= 0) stay with each
// command (exit 1).
#pragma once

#include <CLI/CLI.hpp>
#include <charconv>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>

namespace mktree::tools {

// Decimal digits only (no sign, no space), within T.
template <typename T>
std::optional<T> ParseUnsigned(std::string_view text) {
  static_assert(std::is_unsigned_v<T>);
  T v{};
  if (text.empty() || text[0] < '0' || text[0] > '9') return std::nullopt;  // from_chars skips no sign here
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return v;
}

// An optional '-' then decimal digits, within T.
template <typename T>
std::optional<T> ParseSigned(std::string_view text) {
  static_assert(std::is_signed_v<T> && std::is_integral_v<T>);
  T v{};
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return v;
}

// A decimal floating-point number ("nan" and "inf" included: each command checks its own range).
inline std::optional<double> ParseReal(std::string_view text) {
  double v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return v;
}

// Adds a numeric option stored in *target, parsed as above; a bad value throws CLI::ValidationError
// ("--count: '12abc' is not a whole number from 0 to 18446744073709551615").
template <typename T>
CLI::Option* AddNumberOption(CLI::App* app, const std::string& name, T* target,
                             const std::string& description) {
  const std::string flag = name.substr(name.rfind(',') + 1);
  auto parse = [target, flag](const std::string& text) {
    std::optional<T> v;
    std::string kind;
    if constexpr (std::is_floating_point_v<T>) {
      auto d = ParseReal(text);
      if (d) v = static_cast<T>(*d);
      kind = "a number";
    } else if constexpr (std::is_unsigned_v<T>) {
      v = ParseUnsigned<T>(text);
      kind = "a whole number from 0 to " + std::to_string(std::numeric_limits<T>::max());
    } else {
      v = ParseSigned<T>(text);
      kind = "a whole number from " + std::to_string(std::numeric_limits<T>::min()) + " to " +
             std::to_string(std::numeric_limits<T>::max());
    }
    if (!v) throw CLI::ValidationError(flag, "'" + text + "' is not " + kind);
    *target = *v;
  };
  std::ostringstream def;
  def << *target;
  return app->add_option_function<std::string>(name, parse, description)
      ->type_name(std::is_floating_point_v<T> ? "FLOAT" : (std::is_unsigned_v<T> ? "UINT" : "INT"))
      ->default_str(def.str());
}

}  // namespace mktree::tools
