// Command-line helpers shared by the tools' argument parsers (no engine dependencies
// beyond core): strict number parsing with a one-line reason on failure.
#pragma once

#include "core/core.h"

#include <charconv>
#include <string>
#include <vector>

namespace fulgur::app {

/// Parses the whole of `s` as a T (integers in base 10, doubles in the C locale's form).
/// Throws core::Error(tool, "<what>: not a number: '<s>'") otherwise.
template <class T>
T parse_number(const std::string& s, const char* tool, const char* what) {
    T v{};
    auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || p != s.data() + s.size() || s.empty())
        throw core::Error(tool, std::string(what) + ": not a number: '" + s + "'");
    return v;
}

/// The value of option args[i]: returns args[i + 1] and advances i past it. Throws
/// core::Error(tool, "<option> needs a value") when the option is the last argument.
inline const std::string& option_value(const std::vector<std::string>& args, std::size_t& i, const char* tool) {
    if (i + 1 >= args.size()) throw core::Error(tool, args[i] + " needs a value");
    return args[++i];
}

}  // namespace fulgur::app
