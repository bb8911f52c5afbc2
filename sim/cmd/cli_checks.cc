// sim/cmd/cli_checks.cc — see sim/cmd/cli_checks.h.
#include "sim/cmd/cli_checks.h"

#include <fmt/format.h>

#include <charconv>
#include <cstdint>
#include <limits>
#include <string>

namespace ncosim::sim {

CLI::Validator seed_range() {
  return CLI::Validator(
      [](std::string& s) -> std::string {
        std::uint64_t v = 0;
        const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
        if (s.empty() || ec != std::errc() || end != s.data() + s.size() ||
            v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
          return fmt::format("expected an integer in 0 .. 9223372036854775807 (2^63 - 1), got '{}'",
                             s);
        }
        return std::string();
      },
      "INT in 0 .. 2^63-1");
}

}  // namespace ncosim::sim
