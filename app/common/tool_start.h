// The start and the exit statuses every tool's main() shares, without CLI11: a main that only
// calls its parser (common/*_args.h) does not compile CLI11's headers (~4 s a file, ~12 s under
// the sanitizers).
#pragma once

#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <vector>

namespace fulgur::app {

/// Exit statuses of every tool (also in each --help footer).
inline constexpr int kExitFailure = 1;  ///< the work failed: unreadable scene or file, I/O, GL, ...
inline constexpr int kExitUsage = 2;    ///< the command line is invalid (one-line reason on stderr)

/// The start of a tool's main(): parses argv[1..] with `parse`. Prints the reason and gives
/// kExitUsage on an invalid command line, prints `usage()` and gives 0 for --help, and
/// nullopt (go on with `a`) otherwise.
template <class Args>
std::optional<int> start(int argc, char** argv, Args& a, Args (*parse)(const std::vector<std::string>&),
                         std::string (*usage)()) {
    try {
        a = parse(std::vector<std::string>(argv + 1, argv + argc));
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return kExitUsage;
    }
    if (!a.help) return std::nullopt;
    std::fputs(usage().c_str(), stdout);
    return 0;
}

}  // namespace fulgur::app
