#include "shot_args.h"

#include "camera_arg.h"
#include "cli.h"
#include "core/core.h"
#include "scene/scene.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string_view>

namespace fulgur::app {

namespace {

constexpr std::array<std::string_view, 15> kSwitches = {"sun",
                                                        "sky",
                                                        "silver-lining",
                                                        "glow",
                                                        "glare",
                                                        "bolt",
                                                        "ground",
                                                        "ground-scatter",
                                                        "single",
                                                        "multiple",
                                                        "detail",
                                                        "rain",
                                                        "dither",
                                                        "display-upsample",
                                                        "ground-rain-map"};

constexpr const char* kTool = "fulgur-shot";

constexpr const char* kDescription =
    "Renders one frame of SCENE's storm headless (OSMesa) to OUT.png and prints the per-stage\n"
    "timings as one JSON line.";

// An option naming a file that must end in `extension` ("--vdb must name a .vdb file").
CLI::Option* path_option(CLI::App& app, const std::string& name, std::optional<std::filesystem::path>& target,
                         const std::string& extension, const std::string& help) {
    return app.add_option_function<std::string>(
        name,
        [&target, name, extension](const std::string& s) {
            target = s;
            if (target->extension() != extension)
                throw core::Error(kTool, name + " must name a " + extension + " file, got '" + s + "'");
        },
        help);
}

// fulgur-shot's options, writing into `a`.
void declare(CommandLine& cli, ShotArgs& a) {
    CLI::App& app = cli.app();
    app.add_option("SCENE.json", a.scene, "the scene (JSON)")->type_name("FILE")->required()->check(existing_file());
    app.add_option_function<std::string>(
           "--fgb", [&a](const std::string& s) { a.fgb = s; },
           "baked bases to use (default: the scene's .fgb, baked first if missing or stale)")
        ->type_name("FILE")
        ->check(existing_file());
    add_camera_option(app, a.camera, kTool);
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
    cli.number("--exposure", a.exposure_ev, "stops added to the automatic exposure (0)", -20.0, 20.0, "stops")
        ->type_name("EV in -20..20");
    app.add_option_function<std::string>(
           "--manual-exposure",
           [&a](const std::string& v) {
               a.manual_exposure = parse_number<double>(v, kTool, "--manual-exposure");
               // The shaders take it as a float32 (largest power of ten: 1e38).
               if (!std::isfinite(*a.manual_exposure) || !(*a.manual_exposure > 0.0) || *a.manual_exposure > 1e38)
                   throw core::Error(kTool, "--manual-exposure must be in (0, 1e38]");
           },
           "a fixed exposure (linear multiplier before the tone map, in (0, 1e38]) instead of the automatic one")
        ->type_name("X");
    app.add_option_function<std::string>(
           "--off",
           [&a](const std::string& v) {
               a.off.clear();
               for (std::size_t b = 0; b <= v.size();) {
                   const std::size_t e = std::min(v.find(',', b), v.size());
                   const std::string name = v.substr(b, e - b);
                   if (std::find(kSwitches.begin(), kSwitches.end(), name) == kSwitches.end())
                       throw core::Error(
                           kTool,
                           "--off: \"" + name +
                               "\" is not one of sun, sky, silver-lining, glow, glare, bolt, ground, ground-scatter, "
                               "single, multiple, detail, rain, dither, display-upsample, ground-rain-map");
                   a.off.push_back(name);
                   b = e + 1;
               }
           },
           "run-time switches to turn off, comma-separated: sun, sky, silver-lining (the sun's single scattering "
           "at full resolution: on the lighting grid instead), glow, glare, bolt, ground (ground-scatter: only the "
           "light the cloud scatters onto it), single, multiple, detail "
           "(the march draws the cloud before its sub-voxel detail), rain, dither (the 8-bit output's dither: "
           "smooth images compress far better), display-upsample (the march's radiance upsampled and tone mapped "
           "at every output pixel instead of its display values upsampled), ground-rain-map (each ground pixel "
           "integrates the rain toward the channel's ground lights instead of reading their tabulated "
           "transmittance)")
        ->type_name("A,B,..");
    app.add_option("-o,--output", a.output, "output PNG")->type_name("OUT.png")->required();
    path_option(app, "--reference", a.reference, ".png",
                "also render the frame lit by the reference (--against: the truth or the direct solve; seconds to "
                "minutes) into REF.png, |difference| into REF_diff.png (white = 10% of the reference's maximum), "
                "frame | reference | difference into REF_compare.png, and print the errors and times as JSON")
        ->type_name("REF.png");
    app.add_option(
           "--against", a.against,
           "what --reference renders: truth (Monte Carlo of the frame's lit channel through the full-resolution "
           "density; the default), direct (the scene's own solvers on the frame's point sources) or static (the "
           "frame's sun or moon and sky by Monte Carlo through the full-resolution density in place of their "
           "solves; the lightning as shown)")
        ->check(CLI::IsMember({"truth", "direct", "static"}))
        ->type_name("truth|direct|static");
    cli.number("--truth-paths", a.truth_paths, "Monte Carlo paths of the truth (noise ~ 1/sqrt(N))",
               std::uint64_t(1000), std::uint64_t(1) << 34)
        ->type_name("N");
    add_choice(
        app, "--quality", [&a](const std::string& s) { a.quality = s; }, scene::kQualityPresets,
        "how the frame is lit, its strike's own solve waited for (default: the scene's \"quality\")")
        ->type_name("PRESET");
    cli.number("--strike-grid", a.strike_grid,
               "keep the solved strike's S on the lighting grid refined by REFINE (the quality's \"grid\": "
               "\"transport\", \"refine\": REFINE; a divisor of lighting.downsample above 1; presets that solve "
               "strikes ahead). The preset's paths spread over REFINE^3 the voxels: use reference, or raise "
               "the scene's quality paths, where the noise would show",
               2, 64)
        ->type_name("REFINE");
    app.add_flag("--strike-toward-camera", a.strike_toward_camera,
                 "tally the solved strike's S toward this shot's camera from every voxel (the quality's "
                 "\"directions\": \"camera\"; presets that solve strikes by Monte Carlo: hybrid, per_strike_mc, "
                 "reference): no interpolation between baked directions");
    app.add_flag("--static-toward-camera", a.static_toward_camera,
                 "solve the sun's, moon's and sky's light by Monte Carlo toward this shot's camera, kept on the "
                 "transport grid (transport.static_light: \"solver\": \"monte_carlo\", \"directions\": "
                 "\"camera\", \"grid\": \"transport\"): no interpolation between baked directions; a minute or "
                 "more, cached per camera position");
    app.add_option_function<std::string>(
           "--since-known",
           [&a](const std::string& v) {
               a.since_leader = v == "leader";
               if (a.since_leader) {
                   a.since_known_ms = 0.0;  // set from the strike's timing
                   return;
               }
               const std::string what =
                   "--since-known must be a number of milliseconds in [0, 600000] or \"leader\", got '" + v + "'";
               try {
                   a.since_known_ms = parse_number<double>(v, kTool, "--since-known");
               } catch (const core::Error&) {
                   throw core::Error(kTool, what);
               }
               if (!std::isfinite(*a.since_known_ms) || *a.since_known_ms < 0.0 || *a.since_known_ms > 600'000.0)
                   throw core::Error(kTool, what);
           },
           "the frame as a strike nobody scheduled shows it MS ms of wall time after it became known (0: its first "
           "lit frame; frames at 60 fps meanwhile, lookahead 0; the demo's \"Strike now\": under a preset that "
           "solves strikes ahead it is lit the instant way meanwhile); \"leader\": the strike triggered at its "
           "leader's start, the leader's frames at their own storm time; without it the strike's own solve is "
           "waited for")
        ->type_name("MS|leader");
    app.add_flag("--without-instant", a.without_instant,
                 "with --since-known under a preset that solves strikes ahead (hybrid, per_strike, per_strike_mc, "
                 "reference): the strike as one scheduled with no lookahead, lit by the preset's own solve when "
                 "it is ready and by the bases until then (the preset without the instant way)");
    path_option(app, "--vdb", a.vdb, ".vdb",
                "also write the density and the frame's lightning S in every direction (grids density, S_00, S_01, "
                "...) as OUT.vdb (OpenVDB, metres), for Houdini, Blender or ParaView")
        ->type_name("OUT.vdb");
    path_option(app, "--exr", a.exr, ".exr",
                "also write the frame's linear radiance (W m^-2 sr^-1, before exposure and tone map, without the "
                "eye's glare; float32 R, G, B) as OUT.exr, with the camera, units and frame in its header; with "
                "--reference also the frame lit by the reference as OUT_reference.exr")
        ->type_name("OUT.exr");
    app.add_flag("--exr-passes", a.exr_passes,
                 "with --exr: also the frame's terms apart (layers lightning, static, glow, channel, background, "
                 "which sum to R, G, B) and the cloud's transmittance (T.Y)");
    app.add_option_function<std::string>(
           "--blender",
           [&a](const std::string& s) {
               if (s.empty()) throw core::Error(kTool, "--blender needs a directory");
               a.blender = s;
           },
           "also write what Blender needs to render the same frame into DIR (frame.json: camera, lights, sun, "
           "sky, ground, medium; density.vdb); scripts/blender_scene.py builds the Blender scene from it")
        ->type_name("DIR");
    cli.number("--internal-scale", a.internal_scale,
               "the ray march's resolution over the output's (0.5; 1: one march ray per pixel; with the glare at "
               "least 0.125)",
               0.0625, 1.0)
        ->type_name("X");
}

}  // namespace

std::string shot_usage() { return usage_of<ShotArgs>(kTool, kDescription, declare); }

ShotArgs parse_shot_args(const std::vector<std::string>& args) {
    return parse_args<ShotArgs>(kTool, kDescription, args, declare, [](const CommandLine&, const ShotArgs& a) {
        if (a.exr_passes && !a.exr) throw core::Error(kTool, "--exr-passes goes with --exr OUT.exr");
        if (a.without_instant && !a.since_known_ms)
            throw core::Error(kTool, "--without-instant goes with --since-known");
        std::vector<core::NamedPath> outputs{{"image (-o)", a.output}};
        if (a.exr) outputs.push_back({"EXR (--exr)", *a.exr});
        if (a.reference) {
            outputs.push_back({"reference image", *a.reference});
            outputs.push_back({"difference image", reference_diff_path(*a.reference)});
            outputs.push_back({"comparison image", reference_compare_path(*a.reference)});
            if (a.exr) outputs.push_back({"reference EXR", reference_exr_path(*a.exr)});
        }
        if (outputs.size() == 1) return;
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

std::filesystem::path reference_exr_path(const std::filesystem::path& exr) {
    std::filesystem::path p = exr;
    p.replace_filename(exr.stem().string() + "_reference.exr");
    return p;
}

}  // namespace fulgur::app
