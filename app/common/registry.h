// A name -> function registry and the main() of the tools built on one: fulgur-bench and
// fulgur-study. Each entry file registers itself at static initialization
// (FULGUR_REGISTRY_ENTRY, wrapped by FULGUR_BENCH and FULGUR_STUDY); main() parses
// [--quick] [tool options] [NAME...] with CLI11 and runs the named entries (all if none).
#pragma once

#include "common/cli.h"
#include "core/core.h"

#include <cstdio>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace fulgur::app {

/// The entries of one tool, keyed by name (so --help lists them and "all" runs them sorted).
template <class Context>
struct Registry {
    using Fn = std::function<void(const Context&)>;
    struct Entry {
        std::string help;
        Fn fn;
    };
    static std::map<std::string, Entry>& entries() {
        static std::map<std::string, Entry> r;
        return r;
    }
    /// Adds an entry; one static Registration per entry.
    struct Registration {
        Registration(const char* name, const char* help, Fn fn) { entries()[name] = Entry{help, std::move(fn)}; }
    };
};

#define FULGUR_REGISTRY_CONCAT2(a, b) a##b
#define FULGUR_REGISTRY_CONCAT(a, b) FULGUR_REGISTRY_CONCAT2(a, b)
/// FULGUR_REGISTRY_ENTRY(Context, ident, "name", "help") { ... uses ctx ... } defines and
/// registers the entry's function.
#define FULGUR_REGISTRY_ENTRY(Context, ident, name, help)                                                     \
    static void FULGUR_REGISTRY_CONCAT(registry_fn_, ident)(const Context& ctx);                              \
    static const ::fulgur::app::Registry<Context>::Registration FULGUR_REGISTRY_CONCAT(registry_reg_, ident)( \
        name, help, &FULGUR_REGISTRY_CONCAT(registry_fn_, ident));                                            \
    static void FULGUR_REGISTRY_CONCAT(registry_fn_, ident)([[maybe_unused]] const Context& ctx)

/// What a registry tool's main() says.
struct RegistryTool {
    const char* tool;         ///< the executable, first word of every error
    const char* entry_kind;   ///< "benchmark", "study": "unknown <kind> 'x' (see --help)"
    std::string description;  ///< heads --help, above the list of entries
    int name_width = 10;      ///< the entries' names are padded to this width in the list
};

/// The main() of a registry tool: [--quick] [options] [NAME...] (`options` declares the
/// tool's own; --quick sets ctx.quick). Runs the named entries in the order given, all of
/// them (by name) when none is; --help lists the entries with their help. Exit status 0, 1
/// when an entry throws, 2 on an invalid command line or an unknown name.
template <class Context>
int registry_main(int argc, char** argv, const RegistryTool& t, Context& ctx,
                  const std::function<void(CLI::App&)>& options = {}) {
    const auto& entries = Registry<Context>::entries();
    std::string listing = t.description + "\n";
    for (const auto& [name, e] : entries) {
        std::string padded = name;
        if (padded.size() < std::size_t(t.name_width)) padded.resize(std::size_t(t.name_width), ' ');
        listing += "\n  " + padded + " " + e.help;
    }
    CommandLine cli(t.tool, listing);
    cli.app().add_flag("--quick", ctx.quick, "smaller problems and fewer repeats (smoke runs)");
    if (options) options(cli.app());
    std::vector<std::string> names;
    cli.app().add_option("NAME", names, "which of the above to run (all if none)");
    try {
        if (!cli.parse(std::vector<std::string>(argv + 1, argv + argc))) {
            std::fputs(cli.help().c_str(), stdout);
            return 0;
        }
        for (const std::string& n : names)
            if (!entries.count(n))
                throw core::Error(t.tool, std::string("unknown ") + t.entry_kind + " '" + n + "' (see --help)");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return kExitUsage;
    }
    if (names.empty())
        for (const auto& [name, e] : entries) names.push_back(name);
    try {
        for (const std::string& n : names) entries.at(n).fn(ctx);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", t.tool, e.what());
        return kExitFailure;
    }
    return 0;
}

}  // namespace fulgur::app
