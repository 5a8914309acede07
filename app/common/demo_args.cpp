#include "demo_args.h"

#include "camera_arg.h"
#include "cli.h"
#include "core/core.h"
#include "scene/scene.h"

namespace fulgur::app {

namespace {

constexpr const char* kTool = "fulgur";

constexpr const char* kDescription =
    "Interactive storm demo (default scene: content/scenes/storm.json). Bakes the scene first\n"
    "when no up-to-date .fgb exists. Without a display (or with --headless) it renders N\n"
    "(default 8) frames headless to out/fulgur_NNN.png.\n"
    "Mouse: left drag orbits, wheel zooms. Keys: Space strike now, H hide or show the panels,\n"
    "C print the camera, P screenshot, Esc quit.";

// The demo's options, writing into `a`.
void declare(CommandLine& cli, DemoArgs& a) {
    CLI::App& app = cli.app();
    app.add_option("SCENE.json", a.scene, "the scene (JSON; default content/scenes/storm.json)")
        ->type_name("FILE")
        ->check(existing_file());
    app.add_flag("--headless", a.headless, "render the headless PNG sequence even when a display is available");
    cli.number("--frames", a.frames, "frames of the headless sequence (default 8)", 1, 10000);
    cli.size("--size", a.width, a.height, "window size (default 1280x720; the headless sequence is at most 640x360)",
             16, 8192);
    cli.number("--screenshot-after", a.screenshot_after,
               "write out/screenshot_000.png after N frames and quit (for documentation images)", 1);
    app.add_flag("--screenshot-at-peak", a.screenshot_at_peak,
                 "hold the first strike 2 ms after its return stroke, write out/screenshot_000.png after "
                 "--screenshot-after frames (default 4) and quit");
    app.add_flag("--static-truth", a.static_truth,
                 "press \"Static light against its truth\" on the second frame (a screenshot waits for it and shows "
                 "the truth)");
    app.add_flag("--solve-direct", a.solve_direct,
                 "ask for the second frame's direct solve (on a worker thread; with --screenshot-at-peak the "
                 "screenshot waits for it and shows the direct solve and its figures)");
    app.add_option_function<std::string>(
           "--seed", [&a](const std::string& s) { a.seed = parse_number<std::uint64_t>(s, kTool, "--seed"); },
           "the first strike's seed (default: the scene's)")
        ->type_name("S");
    cli.number("--time-scale", a.time_scale,
               "storm time per wall-clock second (default 0.25: a flash decays in ~12 ms, slowed down so a "
               "software-rendered frame rate shows it)",
               0.001, 10.0);
    app.add_option_function<std::string>(
           "--time-of-day",
           [&a](const std::string& s) {
               a.time_of_day = parse_number<double>(s, kTool, "--time-of-day");
               if (!(*a.time_of_day >= 0.0 && *a.time_of_day <= 24.0))
                   throw core::Error(kTool, "--time-of-day: expected a solar time in [0, 24] hours, got " + s);
           },
           "start with the scene's sun (or moon) moved along its course to solar time H (hours; clamped to "
           "the hours it stands above the horizon); a screenshot waits for its solve")
        ->type_name("H");
    add_camera_option(app, a.camera, kTool);
    cli.number("--orbit", a.orbit_deg_per_s,
               "in the window, turn the camera around its target at this many degrees of azimuth per wall-clock "
               "second (a turntable; 0: still, the default; the panel's \"turn\"; the headless sequence keeps "
               "its camera)",
               -360.0, 360.0);
    app.add_flag_callback(
        "--no-dither", [&a] { a.dither = false; }, "turn the 8-bit dither off (smaller PNGs)");
    app.add_flag_callback(
        "--hide-panels", [&a] { a.panels = false; },
        "start with the panels hidden (H shows them): the window and its screenshots show the storm alone");
    add_choice(
        app, "--quality", [&a](const std::string& s) { a.quality = s; }, scene::kInteractiveQualityPresets,
        "how frames are lit (default: the scene's \"quality\")")
        ->type_name("PRESET");
}

}  // namespace

std::string demo_usage() { return usage_of<DemoArgs>(kTool, kDescription, declare); }

DemoArgs parse_demo_args(const std::vector<std::string>& args) {
    DemoArgs a = parse_args<DemoArgs>(kTool, kDescription, args, declare);
    // A few frames for the panel to lay itself out before the screenshot.
    if (a.screenshot_at_peak && a.screenshot_after == 0) a.screenshot_after = 4;
    return a;
}

}  // namespace fulgur::app
