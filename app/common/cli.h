// The tools' command lines: CLI11 (Debian libcli11-dev) set up the same way for every tool,
// with strict number parsing, ranges and file checks declared beside each option, one-line
// errors (core::Error) and the same exit statuses. No engine dependencies beyond core, so
// the tests check the validation without GL.
#pragma once

#include "common/tool_start.h"
#include "core/core.h"

#include <CLI/CLI.hpp>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>
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

/// An image size parsed from "WxH", each side a base-10 integer in [lo, hi]. Throws
/// core::Error(tool, ...) naming `what` (the option) and the value otherwise.
struct ImageSize {
    int width = 0, height = 0;
};
ImageSize parse_size(const std::string& v, const char* tool, const char* what, int lo, int hi);

/// CLI::ExistingFile without its ":FILE" suffix in --help (the option's type name says FILE).
inline CLI::Validator existing_file() { return CLI::Validator(CLI::ExistingFile).description(""); }

/// An option whose value is one of `names` (e.g. scene::kQualityPresets); `help` is followed
/// by the list, and any other value is a usage error naming the option.
CLI::Option* add_choice(CLI::App& app, const std::string& option, std::function<void(const std::string&)> set,
                        std::span<const std::string_view> names, const std::string& help);

/// A tool's command line over CLI::App: -h/--help, the exit statuses in the --help footer,
/// the last value of a repeated option wins, and every error is a core::Error(tool, reason)
/// with the tools' wording ("unknown option '-x' (see --help)", "<option> needs a value",
/// "<option> is required", "<option> must be in 1..1024", ...).
class CommandLine {
public:
    /// `tool` names the executable (the first word of every error); `description` heads --help.
    CommandLine(const char* tool, const std::string& description);
    CommandLine(const CommandLine&) = delete;
    CommandLine& operator=(const CommandLine&) = delete;

    CLI::App& app() noexcept { return app_; }
    const CLI::App& app() const noexcept { return app_; }
    const char* tool() const noexcept { return tool_; }

    /// An option taking one number, parsed by parse_number (no trailing characters) and
    /// required to lie in [lo, hi]; floating-point values must also be finite. `unit`, when
    /// given, follows the range in messages. The range is part of the option's --help line.
    template <class T>
    CLI::Option* number(const std::string& names, T& target, const std::string& help, T lo,
                        T hi = std::numeric_limits<T>::max(), const char* unit = "");

    /// An option taking an image size "WxH" (parse_size: each side in [lo, hi]).
    CLI::Option* size(const std::string& names, int& width, int& height, const std::string& help, int lo, int hi);

    /// Parses argv[1..]. Returns false when -h/--help was given (print help()). Throws
    /// core::Error(tool, reason) on an invalid command line. Positional arguments that no
    /// option takes are left in extra_positionals() for the tool to judge.
    bool parse(const std::vector<std::string>& args);
    const std::vector<std::string>& extra_positionals() const noexcept { return extra_; }
    /// For tools taking one scene: throws core::Error(tool, "more than one scene given
    /// ('<scene>', '<next>')") when a positional argument is left over.
    void reject_second_scene(const std::filesystem::path& scene) const;

    /// The --help text.
    std::string help() const { return app_.help(); }

private:
    /// Throws core::Error(tool, "unknown option ...") for the first argument no option took
    /// that looks like an option: the first thing to fix on a command line.
    void reject_unknown_options() const;
    /// The name messages use for an option: its first long name, else its first name.
    static std::string label(const std::string& names);
    const char* tool_;
    CLI::App app_;
    std::vector<std::string> extra_;
};

/// A tool's parser and --help text from one declaration: `declare(cli, args)` adds the
/// options, writing into `args`. parse_args returns Args with help = true on -h/--help,
/// rejects a second scene and then calls `check(cli, args)` (checks across options); it
/// throws core::Error(tool, reason) on an invalid command line.
template <class Args, class Declare>
std::string usage_of(const char* tool, const std::string& description, Declare declare) {
    Args a;
    CommandLine cli(tool, description);
    declare(cli, a);
    return cli.help();
}
template <class Args, class Declare>
Args parse_args(const char* tool, const std::string& description, const std::vector<std::string>& args, Declare declare,
                const std::function<void(const CommandLine&, const Args&)>& check = {}) {
    Args a;
    CommandLine cli(tool, description);
    declare(cli, a);
    if (!cli.parse(args)) {
        a = Args{};
        a.help = true;
        return a;
    }
    cli.reject_second_scene(a.scene);
    if (check) check(cli, a);
    return a;
}

template <class T>
CLI::Option* CommandLine::number(const std::string& names, T& target, const std::string& help, T lo, T hi,
                                 const char* unit) {
    static_assert(std::is_arithmetic_v<T>);
    const std::string name = label(names);
    const bool bounded = hi != std::numeric_limits<T>::max() && !(std::is_floating_point_v<T> && std::isinf(hi));
    auto text = [](T v) {
        if constexpr (std::is_floating_point_v<T>) {
            std::ostringstream o;
            o << v;
            return o.str();
        } else {
            return std::to_string(v);
        }
    };
    const std::string range = bounded ? text(lo) + ".." + text(hi) : ">= " + text(lo);
    const std::string suffix = *unit ? std::string(" ") + unit : std::string();
    std::string reason = name + " must be ";
    if (bounded)
        reason += "in " + range + suffix;
    else
        reason += (std::is_floating_point_v<T> ? "finite and " : "") + range + suffix;
    const char* tool = tool_;
    CLI::Option* o = app_.add_option_function<std::string>(
        names,
        [&target, tool, name, reason, lo, hi](const std::string& s) {
            const T v = parse_number<T>(s, tool, name.c_str());
            if constexpr (std::is_floating_point_v<T>) {
                if (!std::isfinite(v)) throw core::Error(tool, reason);
            }
            if (!(v >= lo && v <= hi)) throw core::Error(tool, reason);
            target = v;
        },
        help);
    o->type_name((std::is_floating_point_v<T> ? "X " : "N ") + (bounded ? "in " + range : range) + suffix);
    return o;
}

}  // namespace fulgur::app
