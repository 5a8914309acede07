// fulgur::core — numbers, durations and sizes formatted for people and messages.
#pragma once

#include <string>

namespace fulgur::core {

/// A duration for people: "12.3 s", "4.5 min", "1.2 h" ("?" when negative or not finite).
std::string format_seconds(double seconds);
/// A size for people (powers of ten): "512 B", "12.3 kB", "229.4 MB", "1.19 GB".
std::string format_bytes(double bytes);
/// A number with `significant_digits` significant digits, printf's "%.*g" in the C locale
/// ("0.1", "1e+30", "inf"): 6 for messages, 17 to round-trip any double.
std::string format_number(double v, int significant_digits = 6);

}  // namespace fulgur::core
