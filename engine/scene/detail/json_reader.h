// Internal to fulgur::scene: a strict reader over nlohmann::json that tracks the field path,
// checks types and ranges, and rejects unknown keys. Every error names the file and the
// field as a JSON pointer (RFC 6901, e.g. "storm.json: /medium/albedo", "/lights/0/type")
// and the allowed range or values.
#pragma once

#include "core/core.h"

#include <nlohmann/json.hpp>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fulgur::scene::detail {

/// A closed or half-open numeric interval, printed in error messages as e.g. "(0, 1]".
struct Range {
    double lo, hi;
    bool lo_open = false, hi_open = false;
    bool contains(double v) const noexcept { return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi); }
    std::string str() const;
};

/// A member name as a JSON pointer reference token ("~" -> "~0", "/" -> "~1").
std::string json_pointer_token(std::string_view key);

/// A dotted field path as other modules' validators write it ("lightning.timing.rise_time")
/// as a JSON pointer ("/lightning/timing/rise_time").
std::string dotted_to_pointer(std::string_view dotted);
/// Deepest nesting of arrays and objects a scene file may hold (a scene needs 4 levels).
inline constexpr int kMaxJsonDepth = 32;

/// Parses JSON text strictly: nesting deeper than kMaxJsonDepth, a key repeated in one
/// object, a number outside double's range (1e400) and a UTF-16/32 byte-order mark are errors
/// that name `file` and the field path (or byte offset) where they occur; a UTF-8 byte-order
/// mark is skipped. Nothing recurses with the input's depth.
nlohmann::json parse_json(std::string_view text, const std::string& file);

class JsonObject {
public:
    /// `path` is the JSON pointer of this object ("" for the root).
    JsonObject(const nlohmann::json& j, std::string file, std::string path);

    bool has(std::string_view key) const;
    /// The member exists and is a JSON string (for fields that take a name or an object).
    bool is_string(std::string_view key) const;

    double number(std::string_view key, Range r);
    double number_or(std::string_view key, double fallback, Range r);
    std::int64_t integer(std::string_view key, std::int64_t lo, std::int64_t hi);
    std::int64_t integer_or(std::string_view key, std::int64_t fallback, std::int64_t lo, std::int64_t hi);
    std::uint64_t seed_or(std::string_view key, std::uint64_t fallback);
    bool boolean_or(std::string_view key, bool fallback);
    std::string string(std::string_view key);
    std::string string_or(std::string_view key, std::string fallback);
    /// One of `allowed`; the error lists them.
    std::string choice_or(std::string_view key, std::string fallback, std::span<const std::string_view> allowed);
    std::string choice_or(std::string_view key, std::string fallback, std::initializer_list<std::string_view> allowed) {
        return choice_or(key, std::move(fallback), std::span(allowed.begin(), allowed.size()));
    }
    glm::dvec3 vec3(std::string_view key, Range each);
    glm::dvec3 vec3_or(std::string_view key, glm::dvec3 fallback, Range each);
    glm::dvec2 vec2_or(std::string_view key, glm::dvec2 fallback, Range each);
    core::Int3 int3(std::string_view key, int lo, int hi);
    core::Int3 int3_or(std::string_view key, core::Int3 fallback, int lo, int hi);

    JsonObject object(std::string_view key);
    std::optional<JsonObject> optional_object(std::string_view key);
    std::vector<JsonObject> objects(std::string_view key);  // an array of objects; missing -> empty

    /// Throws if the object holds keys that were never read, naming them and the known keys.
    void finish() const;

    const std::string& file() const noexcept { return file_; }
    std::string field(std::string_view key) const;  // JSON pointer of a member
    [[noreturn]] void fail(std::string_view key, const std::string& what) const;

private:
    // An array of exactly out.size() finite numbers in `each` (`missing` names its shape).
    void numbers(std::string_view key, Range each, std::span<double> out, const char* missing);

    const nlohmann::json* find(std::string_view key);
    const nlohmann::json& j_;
    std::string file_, path_;
    std::set<std::string, std::less<>> known_;
};

}  // namespace fulgur::scene::detail
