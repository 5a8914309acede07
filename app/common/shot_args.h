// fulgur-shot's command line (kept apart from main so tests can check the validation).
#pragma once

#include "scene/scene.h"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace fulgur::app {

struct ShotArgs {
    std::filesystem::path scene;
    std::optional<std::filesystem::path> fgb;  ///< default: the scene's up-to-date .fgb (baked if needed)
    std::uint64_t seed = 1;
    double time = 0.6;
    bool time_after_return_stroke = false;  ///< --time +T: T seconds after the first return stroke's onset
    int width = 640, height = 360;
    int repeat = 1;  ///< --repeat N: render N times, report medians (the first frame compiles shaders); same image
    double exposure_ev = 0.0;               ///< --exposure EV: stops added to the automatic exposure
    std::optional<double> manual_exposure;  ///< --manual-exposure X: a fixed exposure X instead of the automatic one
    /// --off A,B,..: run-time switches turned off (sun, sky, silver-lining, glow, glare, bolt,
    /// ground, ground-scatter, single, multiple, detail, rain, dither, display-upsample,
    /// ground-rain-map), to see or
    /// time a frame without them.
    std::vector<std::string> off;
    std::filesystem::path output;
    /// --reference REF.png: also render the frame lit by the direct solve (the reference the
    /// basis method is measured against) into REF.png, its difference image into
    /// REF_diff.png, and print a second JSON line with the errors and the times.
    std::optional<std::filesystem::path> reference;
    /// --against truth|direct|static: what --reference renders: the truth (Monte Carlo of the
    /// frame's lit channel through the full-resolution density, runtime::truth), the direct
    /// solve (the scene's own solvers on the frame's point sources, no basis), or the static
    /// light's truth (sky::static_truth in place of the sun's and sky's solves).
    std::string against = "truth";
    std::uint64_t truth_paths = 4'000'000;  ///< --truth-paths N: the truth's Monte Carlo paths
    /// --quality PRESET: how the frame is lit (paper, hybrid, per_strike, reference; default:
    /// the scene's "quality"); a strike's own solve is waited for.
    std::optional<std::string> quality;
    /// --strike-grid REFINE: keep the solved strike's S on the lighting grid refined by REFINE
    /// (the quality's "grid": "transport" with "refine": REFINE), for a sharper flash in a still
    /// shot without a new bake (docs/presets.md, "Where a solved strike's S is kept").
    int strike_grid = 0;  ///< 0: the quality's own grid
    /// --static-toward-camera: the sun's, moon's and sky's light solved by Monte Carlo toward
    /// this shot's camera and kept on its transport grid (transport.static_light "solver":
    /// "monte_carlo", "directions": "camera", "grid": "transport"; docs/sky.md, "Toward the
    /// camera").
    bool static_toward_camera = false;
    /// --strike-toward-camera: the solved strike's S tallied toward this shot's camera (the
    /// quality's "directions": "camera"; docs/presets.md).
    bool strike_toward_camera = false;
    /// --since-known MS: the frame as a strike nobody scheduled shows it MS milliseconds of wall
    /// time after it became known (runtime::build_since_known: lookahead 0, frames at 60 fps
    /// meanwhile, then the per-strike work stops and the frame is what exists); 0 is its first
    /// lit frame; under a preset that solves strikes ahead the strike is lit the instant way
    /// meanwhile, as the demo's "Strike now" (FramePipeline::strike_at(..., known_ahead = false)).
    /// Without it the strike's own solve is waited for. `--since-known leader`: the
    /// strike triggered at its leader's start, its leader's frames built at their own storm time
    /// (what "Strike now" shows at --time); since_known_ms is then set from the strike's timing.
    std::optional<double> since_known_ms;
    bool since_leader = false;
    /// --without-instant (with --since-known): the strike counted as scheduled with lookahead 0
    /// under a preset that solves strikes ahead, so no instant tracing lights it meanwhile.
    bool without_instant = false;
    /// --vdb OUT.vdb: also write the density and the frame's lightning S (every direction, on
    /// the lighting grid) as OpenVDB.
    std::optional<std::filesystem::path> vdb;
    /// --exr OUT.exr: also write the frame's linear radiance (W m^-2 sr^-1, before exposure and
    /// tone map, without the eye's glare) as OpenEXR, with the camera and units in the header;
    /// --exr-passes adds the terms apart (view::kLinearPasses) and the transmittance.
    std::optional<std::filesystem::path> exr;
    bool exr_passes = false;
    /// --blender DIR: also write what Blender needs to render the same frame (DIR/frame.json,
    /// DIR/density.vdb; docs/blender.md).
    std::optional<std::filesystem::path> blender;
    /// --internal-scale X: the ray march's resolution over the output's (render::Settings).
    double internal_scale = 0.5;
    /// --camera JSON|FILE: the view (a scene's "camera" object, as JSON text or a file holding
    /// it); default: the scene's camera, else the default view.
    std::optional<scene::CameraSpec> camera;
    bool help = false;
};

/// The --help text.
std::string shot_usage();

/// Parses argv[1..]. Throws core::Error with a one-line reason on any invalid input
/// (unknown option, missing value, malformed number, non-positive size, missing -o, two of
/// the images -o, REF.png, REF_diff.png, REF_compare.png, OUT.exr and OUT_reference.exr being
/// one file, --exr-passes without --exr).
ShotArgs parse_shot_args(const std::vector<std::string>& args);

/// The images --reference REF.png derives: REF_diff.png and REF_compare.png beside it.
std::filesystem::path reference_diff_path(const std::filesystem::path& reference);
std::filesystem::path reference_compare_path(const std::filesystem::path& reference);
/// The reference frame's radiance that --exr OUT.exr with --reference writes: OUT_reference.exr.
std::filesystem::path reference_exr_path(const std::filesystem::path& exr);

}  // namespace fulgur::app
