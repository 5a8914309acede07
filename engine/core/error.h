// fulgur::core — the two tiers of failure. `Error` is thrown for bad *data* (files, scene fields,
// command-line values); its message names where (file, field, byte offset) and what was expected.
// FULGUR_ASSERT aborts on *programmer misuse* (violated preconditions), active in every build type.
#pragma once

#include <stdexcept>
#include <string>

namespace fulgur::core {

/// Bad input (data, files, parameters). `where` names the file, field or byte offset;
/// `what` says what was wrong and what was expected. what() returns "where: what".
class Error : public std::runtime_error {
public:
    Error(std::string where, std::string what);
    const std::string& where() const noexcept { return where_; }
    const std::string& reason() const noexcept { return reason_; }

private:
    std::string where_;
    std::string reason_;
};

/// Aborts with file:line and the message. For programmer misuse only, never for data.
[[noreturn]] void assertion_failed(const char* expr, const char* file, int line, const char* msg);

#define FULGUR_ASSERT(cond, msg)                                                       \
    do {                                                                               \
        if (!(cond)) ::fulgur::core::assertion_failed(#cond, __FILE__, __LINE__, msg); \
    } while (0)

}  // namespace fulgur::core
