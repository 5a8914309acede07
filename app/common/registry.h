// A name -> function registry and the main() of the tools built on one: fulgur-bench and
// fulgur-study. Each entry file registers itself at static initialization
// (FULGUR_REGISTRY_ENTRY, wrapped by FULGUR_BENCH and FULGUR_STUDY); main() parses
// [--quick] [tool options] [NAME...] with CLI11 (in registry.cpp, so the entry files do not
// compile it) and runs the named entries (all if none).
#pragma once

#include "core/core.h"

#include <cstdio>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace CLI {
class App;
}

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

/// The command line of a registry tool, apart from its entries' types (common/registry.cpp,
/// the one place CLI11 is compiled for the entry files): [--quick] [options] [NAME...] over
/// `entries` (name -> help). Runs `run(name)` for the names given, in that order, or for all
/// of them (sorted) when none is. Exit status 0, 1 when `run` throws, 2 on an invalid command
/// line or an unknown name.
int run_registry(int argc, char** argv, const RegistryTool& t, const std::map<std::string, std::string>& entries,
                 bool& quick, const std::function<void(CLI::App&)>& options,
                 const std::function<void(const std::string&)>& run);

/// The main() of a registry tool: run_registry() over Registry<Context>'s entries, --quick
/// setting ctx.quick (`options` declares the tool's own).
template <class Context>
int registry_main(int argc, char** argv, const RegistryTool& t, Context& ctx,
                  const std::function<void(CLI::App&)>& options = {}) {
    const auto& entries = Registry<Context>::entries();
    std::map<std::string, std::string> helps;
    for (const auto& [name, e] : entries) helps[name] = e.help;
    return run_registry(argc, argv, t, helps, ctx.quick, options, [&](const std::string& n) { entries.at(n).fn(ctx); });
}

}  // namespace fulgur::app
