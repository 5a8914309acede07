#include "bake_args.h"

#include "cli.h"
#include "core/core.h"

#include <algorithm>
#include <cmath>

namespace fulgur::app {

namespace {

constexpr const char* kTool = "fulgur-bake";

// "L[:W],...": light indices with optional weights (default 1).
std::vector<ExportLight> parse_export(const std::string& v) {
    std::vector<ExportLight> lights;
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
        lights.push_back(e);
        pos = comma + 1;
    }
    return lights;
}

// fulgur-bake's options, writing into `a`.
void declare(CommandLine& cli, BakeArgs& a) {
    CLI::App& app = cli.app();
    app.add_option("SCENE.json", a.scene, "the scene to bake (JSON)")
        ->type_name("FILE")
        ->required()
        ->check(existing_file());
    app.add_option_function<std::string>(
           "-o,--output", [&a](const std::string& s) { a.output = s; }, "output (default: the scene's path with .fgb)")
        ->type_name("OUT.fgb");
    app.add_flag("--dry-run", a.dry_run, "print the plan only");
    app.add_flag("--force", a.force, "bake even if OUT.fgb is up to date");
    app.add_option_function<std::string>(
           "--report", [&a](const std::string& s) { a.report = s; },
           "per-stage times, sizes, kept coefficients, compression error, iterations")
        ->type_name("F.json");
    cli.number("--threads", a.threads, "worker threads (default: all cores)", 1, 1024);
    // Repeated --export lists add up.
    app.add_option_function<std::vector<std::string>>(
           "--export",
           [&a](const std::vector<std::string>& lists) {
               for (const std::string& s : lists)
                   for (const ExportLight& e : parse_export(s)) a.export_lights.push_back(e);
           },
           "sum of lights L with weights W (default 1) for direction M, written as PREFIX_raw.nrrd "
           "(uncompressed, solved again) and PREFIX_compressed.nrrd (from the .fgb), float32 NRRD for ParaView")
        ->expected(1)
        ->allow_extra_args(false)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
        ->type_name("L[:W],..");
    cli.number("--direction", a.export_direction, "output direction index for --export (default 0)", 0);
    app.add_option("--nrrd", a.export_prefix, "output prefix for --export")->type_name("PREFIX");
    app.add_option("--vdb", a.vdb_prefix,
                   "write --export's sum from the .fgb for every direction (grids S_00, S_01, ...) with the "
                   "density as PREFIX.vdb (OpenVDB, metres), for Houdini, Blender or ParaView")
        ->type_name("PREFIX");
    app.add_flag_callback(
        "--no-checkpoint", [&a] { a.checkpoint = false; },
        "do not keep finished lights in OUT.fgb.ckpt/ (by default a killed bake resumes from it)");
    app.add_flag("--fresh", a.fresh, "discard the checkpoint OUT.fgb.ckpt/ and bake from scratch");
    cli.number("--stop-after", a.stop_after,
               "testing restarts: kill the process (SIGKILL) once the checkpoint holds N lights", std::size_t(1));
}

constexpr const char* kDescription =
    "Bakes SCENE's virtual-light bases (Dobashi 2007 sections 5-6) into a .fgb file. Prints the\n"
    "plan first (what is simulated and why, light count, expected size and time). Finished lights\n"
    "are kept in OUT.fgb.ckpt/ until the file is written, so a killed bake resumes where it\n"
    "stopped. Under mpirun or srun the ranks share the lights (docs/distributed.md).";

}  // namespace

std::string bake_usage() { return usage_of<BakeArgs>(kTool, kDescription, declare); }

BakeArgs parse_bake_args(const std::vector<std::string>& args) {
    return parse_args<BakeArgs>(kTool, kDescription, args, declare, [](const CommandLine& cli, const BakeArgs& a) {
        const bool have_nrrd = cli.app().count("--nrrd") > 0, have_direction = cli.app().count("--direction") > 0;
        const bool have_vdb = cli.app().count("--vdb") > 0;
        if (!a.export_lights.empty() && !have_nrrd && !have_vdb)
            throw core::Error(kTool, "--export needs --nrrd PREFIX or --vdb PREFIX");
        if (a.export_lights.empty() && (have_nrrd || have_direction || have_vdb))
            throw core::Error(kTool, "--nrrd, --vdb and --direction only go with --export");
        if (have_direction && !have_nrrd)
            throw core::Error(kTool, "--direction only goes with --nrrd (--vdb writes every direction)");
        if (a.stop_after && !a.checkpoint) throw core::Error(kTool, "--stop-after needs the checkpoint");
        if (!a.export_lights.empty() && a.dry_run)
            throw core::Error(kTool, "--export needs a bake; it cannot go with --dry-run");
    });
}

}  // namespace fulgur::app
