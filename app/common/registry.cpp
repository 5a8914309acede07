// The command line of fulgur-bench and fulgur-study (common/registry.h).
#include "common/registry.h"

#include "common/cli.h"

namespace fulgur::app {

int run_registry(int argc, char** argv, const RegistryTool& t, const std::map<std::string, std::string>& entries,
                 bool& quick, const std::function<void(CLI::App&)>& options,
                 const std::function<void(const std::string&)>& run) {
    std::string listing = t.description + "\n";
    for (const auto& [name, help] : entries) {
        std::string padded = name;
        if (padded.size() < std::size_t(t.name_width)) padded.resize(std::size_t(t.name_width), ' ');
        listing += "\n  " + padded + " " + help;
    }
    CommandLine cli(t.tool, listing);
    cli.app().add_flag("--quick", quick, "smaller problems and fewer repeats (smoke runs)");
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
        for (const auto& [name, help] : entries) names.push_back(name);
    try {
        for (const std::string& n : names) run(n);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", t.tool, e.what());
        return kExitFailure;
    }
    return 0;
}

}  // namespace fulgur::app
