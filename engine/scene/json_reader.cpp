#include "scene/detail/json_reader.h"

#include <cmath>
#include <cstdio>
#include <limits>

namespace fulgur::scene::detail {

namespace {

// A short description of a value for messages. Containers are summarized, never dumped: a
// value's text can be megabytes long.
std::string describe(const nlohmann::json& v) {
    if (v.is_array()) return "an array of " + std::to_string(v.size()) + " element(s)";
    if (v.is_object()) return "an object with " + std::to_string(v.size()) + " key(s)";
    std::string s = v.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    if (s.size() > 60) s = s.substr(0, 57) + "...";
    return s + " (" + v.type_name() + ")";
}

// The field path of the value being parsed as a JSON pointer, kept from the parser's events
// ("/a/b/2/c"), with
// the keys each open object has seen.
class PathTracker {
public:
    explicit PathTracker(const std::string& file) : file_(file) {}

    bool event(int depth, nlohmann::json::parse_event_t e, const nlohmann::json& parsed) {
        using E = nlohmann::json::parse_event_t;
        switch (e) {
            case E::object_start:
            case E::array_start:
                if (depth >= kMaxJsonDepth)
                    throw core::Error(where(), "nesting deeper than " + std::to_string(kMaxJsonDepth) +
                                                   " levels of arrays and objects; a scene needs a few");
                frames_.push_back({e == E::array_start, false, {}, 0, {}});
                break;
            case E::key: {
                Frame& f = frames_.back();
                f.key = parsed.get<std::string>();
                f.has_key = true;
                if (!f.keys.insert(f.key).second)
                    throw core::Error(where(),
                                      "duplicate key (the same key twice in one object; which one was "
                                      "meant is unclear)");
                break;
            }
            case E::value:
                done_element();
                break;
            case E::object_end:
            case E::array_end:
                frames_.pop_back();
                done_element();
                break;
        }
        return true;
    }

    /// "file: pointer" of the value being parsed (the file alone at the top level).
    std::string where() const {
        std::string p;
        for (const Frame& f : frames_) {
            if (f.array)
                p += "/" + std::to_string(f.index);
            else if (f.has_key)
                p += "/" + json_pointer_token(f.key);
        }
        return p.empty() ? file_ : file_ + ": " + p;
    }

private:
    struct Frame {
        bool array;
        bool has_key;                             // objects: a key has been read
        std::string key;                          // objects: the key being parsed
        std::size_t index;                        // arrays: the element being parsed
        std::set<std::string, std::less<>> keys;  // objects: keys seen so far
    };
    void done_element() {
        if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    }
    const std::string& file_;
    std::vector<Frame> frames_;
};

}  // namespace

nlohmann::json parse_json(std::string_view text, const std::string& file) {
    auto starts = [&](std::string_view p) { return text.substr(0, p.size()) == p; };
    if (starts("\xEF\xBB\xBF"))
        text.remove_prefix(3);  // a UTF-8 byte-order mark carries no meaning
    else if (starts("\xFF\xFE") || starts("\xFE\xFF") || starts(std::string_view("\0\0\xFE\xFF", 4)))
        throw core::Error(file + " (byte 0)", "UTF-16 or UTF-32 text (byte-order mark); scene files are UTF-8");
    PathTracker path(file);
    try {
        return nlohmann::json::parse(text, [&path](int depth, nlohmann::json::parse_event_t e, nlohmann::json& v) {
            return path.event(depth, e, v);
        });
    } catch (const nlohmann::json::parse_error& e) {
        // e.byte is the 1-based position of the offending character.
        // The message quotes the last token read, which can be as long as the file: cut it.
        std::string what = e.what();
        if (what.size() > 240) what = what.substr(0, 237) + "...";
        throw core::Error(file + " (byte " + std::to_string(e.byte) + ")", "invalid JSON: " + what);
    } catch (const nlohmann::json::out_of_range&) {
        // The parser's only range error: a number too large for a double (e.g. 1e400).
        throw core::Error(path.where(), "number out of range (beyond +-1.8e308, the largest double)");
    }
}

std::string Range::str() const {
    auto bound = [](double v) {
        if (v == std::numeric_limits<double>::infinity()) return std::string("inf");
        if (v == -std::numeric_limits<double>::infinity()) return std::string("-inf");
        return core::format_number(v, 10);
    };
    return std::string(lo_open ? "(" : "[") + bound(lo) + ", " + bound(hi) + (hi_open ? ")" : "]");
}

JsonObject::JsonObject(const nlohmann::json& j, std::string file, std::string path)
    : j_(j), file_(std::move(file)), path_(std::move(path)) {
    if (!j_.is_object())
        throw core::Error(file_ + ": " + (path_.empty() ? std::string("/") : path_),
                          "expected a JSON object, got " + describe(j_));
}

std::string json_pointer_token(std::string_view key) {
    std::string t;
    for (char c : key) {
        if (c == '~') {
            t += "~0";
        } else if (c == '/') {
            t += "~1";
        } else if ((unsigned char)c < 0x20 || c == 0x7f) {
            // A control character (a NUL would end the message where it is printed as a C
            // string) is shown as its JSON escape.
            char esc[8];
            std::snprintf(esc, sizeof esc, "\\u%04x", unsigned((unsigned char)c));
            t += esc;
        } else {
            t += c;
        }
    }
    return t;
}

std::string dotted_to_pointer(std::string_view dotted) {
    std::string out;
    std::size_t start = 0;
    while (start <= dotted.size()) {
        const std::size_t dot = dotted.find('.', start);
        const std::size_t end = dot == std::string_view::npos ? dotted.size() : dot;
        out += "/" + json_pointer_token(dotted.substr(start, end - start));
        if (dot == std::string_view::npos) break;
        start = dot + 1;
    }
    return out;
}

std::string JsonObject::field(std::string_view key) const { return path_ + "/" + json_pointer_token(key); }

void JsonObject::fail(std::string_view key, const std::string& what) const {
    throw core::Error(file_ + ": " + field(key), what);
}

bool JsonObject::has(std::string_view key) const { return j_.contains(key); }

bool JsonObject::is_string(std::string_view key) const {
    const auto it = j_.find(key);
    return it != j_.end() && it->is_string();
}

const nlohmann::json* JsonObject::find(std::string_view key) {
    known_.emplace(key);
    auto it = j_.find(key);
    return it == j_.end() ? nullptr : &*it;
}

double JsonObject::number(std::string_view key, Range r) {
    const nlohmann::json* v = find(key);
    if (!v) fail(key, "required number in " + r.str() + " is missing");
    if (!v->is_number()) fail(key, "expected a number in " + r.str() + ", got " + describe(*v));
    const double d = v->get<double>();
    if (!std::isfinite(d) || !r.contains(d))
        fail(key, "value " + core::format_number(d, 10) + " is outside the allowed range " + r.str());
    return d;
}

double JsonObject::number_or(std::string_view key, double fallback, Range r) {
    return j_.contains(key) ? number(key, r) : (known_.emplace(key), fallback);
}

std::int64_t JsonObject::integer(std::string_view key, std::int64_t lo, std::int64_t hi) {
    const nlohmann::json* v = find(key);
    const std::string range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    if (!v) fail(key, "required integer in " + range + " is missing");
    if (!v->is_number_integer()) fail(key, "expected an integer in " + range + ", got " + describe(*v));
    if (v->is_number_unsigned() && v->get<std::uint64_t>() > std::uint64_t(std::numeric_limits<std::int64_t>::max()))
        fail(key, "value is outside the allowed range " + range);
    const std::int64_t i = v->get<std::int64_t>();
    if (i < lo || i > hi) fail(key, "value " + std::to_string(i) + " is outside the allowed range " + range);
    return i;
}

std::int64_t JsonObject::integer_or(std::string_view key, std::int64_t fallback, std::int64_t lo, std::int64_t hi) {
    return j_.contains(key) ? integer(key, lo, hi) : (known_.emplace(key), fallback);
}

std::uint64_t JsonObject::seed_or(std::string_view key, std::uint64_t fallback) {
    const nlohmann::json* v = find(key);
    if (!v) return fallback;
    if (!v->is_number_integer() || (v->is_number_integer() && !v->is_number_unsigned() && v->get<std::int64_t>() < 0))
        fail(key, "expected a non-negative integer seed, got " + describe(*v));
    return v->get<std::uint64_t>();
}

bool JsonObject::boolean_or(std::string_view key, bool fallback) {
    const nlohmann::json* v = find(key);
    if (!v) return fallback;
    if (!v->is_boolean()) fail(key, "expected true or false, got " + describe(*v));
    return v->get<bool>();
}

std::string JsonObject::string(std::string_view key) {
    const nlohmann::json* v = find(key);
    if (!v) fail(key, "required string is missing");
    if (!v->is_string()) fail(key, "expected a string, got " + describe(*v));
    std::string s = v->get<std::string>();
    // "\u0000" is valid JSON, but a NUL ends a C string: a path would be cut short silently.
    if (const auto nul = s.find('\0'); nul != std::string::npos)
        fail(key, "the string holds a NUL character (\\u0000) at position " + std::to_string(nul));
    return s;
}

std::string JsonObject::string_or(std::string_view key, std::string fallback) {
    return j_.contains(key) ? string(key) : (known_.emplace(key), fallback);
}

std::string JsonObject::choice_or(std::string_view key, std::string fallback,
                                  std::span<const std::string_view> allowed) {
    std::string list;
    for (auto a : allowed) list += (list.empty() ? "\"" : ", \"") + std::string(a) + "\"";
    const nlohmann::json* v = find(key);
    if (!v) return fallback;
    if (!v->is_string()) fail(key, "expected one of " + list + ", got " + describe(*v));
    const std::string s = v->get<std::string>();
    for (auto a : allowed)
        if (s == a) return s;
    fail(key, "\"" + s + "\" is not one of " + list);
}

void JsonObject::numbers(std::string_view key, Range each, std::span<double> out, const char* missing) {
    const nlohmann::json* v = find(key);
    if (!v) fail(key, std::string("required ") + missing + " is missing");
    if (!v->is_array() || v->size() != out.size())
        fail(key, "expected an array of " + std::to_string(out.size()) + " numbers, got " + describe(*v));
    for (std::size_t i = 0; i < out.size(); ++i) {
        const auto& e = (*v)[i];
        if (!e.is_number()) fail(key, "element " + std::to_string(i) + " is not a number: " + describe(e));
        const double d = e.get<double>();
        if (!std::isfinite(d) || !each.contains(d))
            fail(key, "element " + std::to_string(i) + " = " + core::format_number(d, 10) +
                          " is outside the allowed range " + each.str());
        out[i] = d;
    }
}

glm::dvec3 JsonObject::vec3(std::string_view key, Range each) {
    double v[3];
    numbers(key, each, v, "[x, y, z]");
    return {v[0], v[1], v[2]};
}

glm::dvec3 JsonObject::vec3_or(std::string_view key, glm::dvec3 fallback, Range each) {
    return j_.contains(key) ? vec3(key, each) : (known_.emplace(key), fallback);
}

glm::dvec2 JsonObject::vec2_or(std::string_view key, glm::dvec2 fallback, Range each) {
    if (!j_.contains(key)) return known_.emplace(key), fallback;
    double v[2];
    numbers(key, each, v, "[x, y]");
    return {v[0], v[1]};
}

core::Int3 JsonObject::int3(std::string_view key, int lo, int hi) {
    const nlohmann::json* v = find(key);
    const std::string range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    if (!v) fail(key, "required [nx, ny, nz] is missing");
    if (!v->is_array() || v->size() != 3)
        fail(key, "expected an array of 3 integers in " + range + ", got " + describe(*v));
    int n[3];
    for (int i = 0; i < 3; ++i) {
        const auto& e = (*v)[std::size_t(i)];
        if (!e.is_number_integer()) fail(key, "element " + std::to_string(i) + " is not an integer: " + describe(e));
        const auto x = e.get<std::int64_t>();
        const bool too_big = e.is_number_unsigned() && e.get<std::uint64_t>() > std::uint64_t(hi);
        if (too_big || x < lo || x > hi)
            fail(key, "element " + std::to_string(i) + " = " + e.dump() + " is outside the allowed range " + range);
        n[i] = int(x);
    }
    return {n[0], n[1], n[2]};
}

core::Int3 JsonObject::int3_or(std::string_view key, core::Int3 fallback, int lo, int hi) {
    return j_.contains(key) ? int3(key, lo, hi) : (known_.emplace(key), fallback);
}

JsonObject JsonObject::object(std::string_view key) {
    const nlohmann::json* v = find(key);
    if (!v) fail(key, "required object is missing");
    if (!v->is_object()) fail(key, "expected an object, got " + describe(*v));
    return JsonObject(*v, file_, field(key));
}

std::optional<JsonObject> JsonObject::optional_object(std::string_view key) {
    if (!j_.contains(key)) {
        known_.emplace(key);
        return std::nullopt;
    }
    return object(key);
}

std::vector<JsonObject> JsonObject::objects(std::string_view key) {
    std::vector<JsonObject> out;
    const nlohmann::json* v = find(key);
    if (!v) return out;
    if (!v->is_array()) fail(key, "expected an array of objects, got " + describe(*v));
    for (std::size_t i = 0; i < v->size(); ++i) {
        const std::string p = field(key) + "/" + std::to_string(i);
        if (!(*v)[i].is_object()) throw core::Error(file_ + ": " + p, "expected an object, got " + describe((*v)[i]));
        out.emplace_back((*v)[i], file_, p);
    }
    return out;
}

void JsonObject::finish() const {
    for (auto it = j_.begin(); it != j_.end(); ++it) {
        if (known_.count(it.key())) continue;
        std::string list;
        for (const auto& k : known_) list += (list.empty() ? "" : ", ") + k;
        throw core::Error(file_ + ": " + field(it.key()), "unknown key; allowed keys here: " + list);
    }
}

}  // namespace fulgur::scene::detail
