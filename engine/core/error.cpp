#include "core/core.h"

#include <cstdio>
#include <cstdlib>

namespace fulgur::core {

namespace {
std::string join(const std::string& where, const std::string& what) {
    return where.empty() ? what : where + ": " + what;
}
}  // namespace

Error::Error(std::string where, std::string what)
    : std::runtime_error(join(where, what)), where_(std::move(where)), reason_(std::move(what)) {}

void assertion_failed(const char* expr, const char* file, int line, const char* msg) {
    std::fprintf(stderr, "fulgur: assertion failed at %s:%d: %s (%s)\n", file, line, msg, expr);
    std::fflush(stderr);
    std::abort();
}

}  // namespace fulgur::core
