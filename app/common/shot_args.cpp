#include "shot_args.h"

#include "cli.h"
#include "core/core.h"

#include <cmath>

namespace fulgur::app {

namespace {

constexpr const char* kTool = "fulgur-shot";

constexpr const char* kDescription =
    "Renders one frame of SCENE's storm headless (OSMesa) to OUT.png and prints the per-stage\n"
    "timings as one JSON line.";

// fulgur-shot's options, writing into `a`.
void declare(CommandLine& cli, ShotArgs& a) {
    CLI::App& app = cli.app();
    app.add_option("SCENE.json", a.scene, "the scene (JSON)")->type_name("FILE")->required()->check(existing_file());
    app.add_option_function<std::string>(
           "--fgb", [&a](const std::string& s) { a.fgb = s; },
           "baked bases to use (default: the scene's .fgb, baked first if missing or stale)")
        ->type_name("FILE")
        ->check(existing_file());
    cli.number("--seed", a.seed, "strike seed (unsigned integer); a strike starts at t = 0", std::uint64_t(0))
        ->type_name("S")
        ->required();
    app.add_option_function<std::string>(
           "--time",
           [&a](std::string v) {
               a.time_after_return_stroke = !v.empty() && v[0] == '+';
               if (a.time_after_return_stroke) v.erase(0, 1);
               a.time = parse_number<double>(v, kTool, "--time");
               if (!std::isfinite(a.time) || a.time < 0.0) throw core::Error(kTool, "--time must be finite and >= 0");
           },
           "seconds after the strike start (>= 0); +T: T seconds after the first return stroke's onset (the "
           "stepped leader's duration depends on the bolt)")
        ->type_name("[+]T")
        ->required();
    cli.size("--size", a.width, a.height, "image size in pixels", 1, 8192)->required();
    cli.number("--repeat", a.repeat,
               "render the frame N times and report median stage times (the image written is the same as one render's)",
               1, 1000);
    cli.number("--exposure", a.exposure_ev, "exposure change in stops from the default (0)", -20.0, 20.0, "stops")
        ->type_name("EV in -20..20");
    app.add_option("-o,--output", a.output, "output PNG")->type_name("OUT.png")->required();
    app.add_option_function<std::string>(
           "--reference",
           [&a](const std::string& s) {
               a.reference = s;
               if (a.reference->extension() != ".png")
                   throw core::Error(kTool, "--reference must name a .png file, got '" + s + "'");
           },
           "also render the frame lit by the direct solve (exact single scattering + the scene's solver on the "
           "frame's point sources, no basis; seconds) into REF.png, |difference| into REF_diff.png (white = 10% "
           "of the reference's maximum), basis | direct | difference into REF_compare.png, and print the errors "
           "and times as JSON")
        ->type_name("REF.png");
}

}  // namespace

std::string shot_usage() { return usage_of<ShotArgs>(kTool, kDescription, declare); }

ShotArgs parse_shot_args(const std::vector<std::string>& args) {
    return parse_args<ShotArgs>(kTool, kDescription, args, declare, [](const CommandLine&, const ShotArgs& a) {
        if (!a.reference) return;
        const core::NamedPath outputs[] = {{"image (-o)", a.output},
                                           {"reference image", *a.reference},
                                           {"difference image", reference_diff_path(*a.reference)},
                                           {"comparison image", reference_compare_path(*a.reference)}};
        try {
            core::check_distinct_files({}, outputs);
        } catch (const core::Error& e) {
            throw core::Error(kTool, e.what());
        }
    });
}

std::filesystem::path reference_diff_path(const std::filesystem::path& reference) {
    std::filesystem::path p = reference;
    p.replace_filename(reference.stem().string() + "_diff.png");
    return p;
}

std::filesystem::path reference_compare_path(const std::filesystem::path& reference) {
    std::filesystem::path p = reference;
    p.replace_filename(reference.stem().string() + "_compare.png");
    return p;
}

}  // namespace fulgur::app
