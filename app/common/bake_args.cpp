#include "bake_args.h"

#include "args.h"
#include "core/core.h"

#include <algorithm>
#include <cmath>

namespace fulgur::app {

namespace {
constexpr const char* kTool = "fulgur-bake";
}

std::string bake_usage() {
    return "usage: fulgur-bake SCENE.json [-o OUT.fgb] [--dry-run] [--force] [--report FILE.json] [--threads N]\n"
           "                   [--export L[:W],... [--direction M] --nrrd PREFIX]\n"
           "Bakes SCENE's virtual-light bases (Dobashi 2007 sections 5-6) into a .fgb file. Prints the\n"
           "plan first (what is simulated and why, light count, expected size and time).\n"
           "  -o OUT.fgb        output (default: the scene's path with .fgb)\n"
           "  --dry-run         print the plan only\n"
           "  --force           bake even if OUT.fgb is up to date\n"
           "  --report F.json   per-stage times, sizes, kept coefficients, compression error, iterations\n"
           "  --threads N       worker threads (default: all cores)\n"
           "  --export L[:W],.. sum of lights L with weights W (default 1) for direction M, written as\n"
           "                    PREFIX_raw.nrrd (uncompressed, solved again) and PREFIX_compressed.nrrd\n"
           "                    (from the .fgb), float32 NRRD for ParaView\n"
           "  --direction M     output direction index for --export (default 0)\n"
           "  --nrrd PREFIX     output prefix for --export\n"
           "  --help            this text\n";
}

BakeArgs parse_bake_args(const std::vector<std::string>& args) {
    BakeArgs a;
    bool have_nrrd = false, have_direction = false;
    auto value = [&](std::size_t& i) -> const std::string& { return option_value(args, i, kTool); };
    for (std::size_t i = 0; i < args.size(); ++i) {
        const std::string& s = args[i];
        if (s == "--help" || s == "-h") {
            a.help = true;
            return a;
        } else if (s == "-o" || s == "--output") {
            a.output = value(i);
        } else if (s == "--dry-run") {
            a.dry_run = true;
        } else if (s == "--force") {
            a.force = true;
        } else if (s == "--report") {
            a.report = value(i);
        } else if (s == "--threads") {
            a.threads = parse_number<int>(value(i), kTool, "--threads");
            if (a.threads < 1 || a.threads > 1024) throw core::Error(kTool, "--threads must be in 1..1024");
        } else if (s == "--export") {
            const std::string& v = value(i);
            std::size_t pos = 0;
            while (pos <= v.size()) {
                const std::size_t comma = std::min(v.find(',', pos), v.size());
                const std::string item = v.substr(pos, comma - pos);
                const std::size_t colon = item.find(':');
                ExportLight e;
                e.light = parse_number<std::uint32_t>(item.substr(0, colon), kTool, "--export light");
                if (colon != std::string::npos) {
                    e.weight = parse_number<double>(item.substr(colon + 1), kTool, "--export weight");
                    if (!std::isfinite(e.weight)) throw core::Error(kTool, "--export: weight must be finite");
                }
                a.export_lights.push_back(e);
                pos = comma + 1;
            }
        } else if (s == "--direction") {
            a.export_direction = parse_number<int>(value(i), kTool, "--direction");
            if (a.export_direction < 0) throw core::Error(kTool, "--direction must be >= 0");
            have_direction = true;
        } else if (s == "--nrrd") {
            a.export_prefix = value(i);
            have_nrrd = true;
        } else if (!s.empty() && s[0] == '-') {
            throw core::Error(kTool, "unknown option '" + s + "' (see --help)");
        } else if (a.scene.empty()) {
            a.scene = s;
        } else {
            throw core::Error(kTool, "more than one scene given ('" + a.scene.string() + "', '" + s + "')");
        }
    }
    if (a.scene.empty()) throw core::Error(kTool, "no SCENE.json given (see --help)");
    if (!a.export_lights.empty() && !have_nrrd) throw core::Error(kTool, "--export needs --nrrd PREFIX");
    if (a.export_lights.empty() && (have_nrrd || have_direction))
        throw core::Error(kTool, "--nrrd and --direction only go with --export");
    if (!a.export_lights.empty() && a.dry_run)
        throw core::Error(kTool, "--export needs a bake; it cannot go with --dry-run");
    return a;
}

}  // namespace fulgur::app
