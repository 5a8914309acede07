// fulgur's (the demo's) command line (kept apart from main so tests can check the validation).
#pragma once

#include "scene/scene.h"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace fulgur::app {

struct DemoArgs {
    std::filesystem::path scene = "content/scenes/storm.json";
    bool headless = false;  ///< --headless: the headless PNG sequence even with a display
    int frames = 8;         ///< --frames N: length of the headless sequence
    int width = 1280, height = 720;
    int screenshot_after = 0;           ///< --screenshot-after N: write a screenshot after N frames and quit (0: never)
    bool screenshot_at_peak = false;    ///< hold 2 ms after the first return stroke, screenshot after 4 frames
    bool solve_direct = false;          ///< press "against the direct solve" on the second frame
    bool static_truth = false;          ///< press "Static light against its truth" on the second frame
    std::optional<std::uint64_t> seed;  ///< the first strike's seed (default: the scene's)
    double time_scale = 0.25;           ///< storm seconds per wall-clock second
    bool dither = true;                 ///< --no-dither turns the 8-bit dither off
    bool panels = true;                 ///< --hide-panels starts without the ImGui windows
    double orbit_deg_per_s = 0.0;       ///< --orbit X: the camera turns around its target at X deg/s
    std::optional<std::string> quality;  ///< --quality PRESET: paper, hybrid or per_strike (default: the scene's)
    std::optional<double> time_of_day;   ///< --time-of-day H: the sun moved to solar time H at the start
    /// --camera JSON|FILE: the first view (a scene's "camera" object, as JSON text or a file
    /// holding it); default: the scene's camera, else the default view.
    std::optional<scene::CameraSpec> camera;
    bool help = false;
};

/// The --help text.
std::string demo_usage();

/// Parses argv[1..]. Throws core::Error with a one-line reason on any invalid input.
DemoArgs parse_demo_args(const std::vector<std::string>& args);

}  // namespace fulgur::app
