// fulgur: the interactive storm demo (GLFW window + Dear ImGui panel). Without a display it
// says so and renders a short headless PNG sequence through OSMesa into out/.
#include "common/demo_args.h"
#include "common/tool_start.h"
#include "common/view_cli.h"
#include "core/core.h"
#include "demo/panel.h"
#include "demo/shell.h"
#include "demo/slice_window.h"
#include "demo/time_of_day.h"
#include "platform/platform.h"
#include "render/render.h"

#include <imgui.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

using namespace fulgur;

namespace {

// Writes frame i of a headless sequence to out/fulgur_NNN.png; returns the name.
std::string write_sequence_frame(platform::Context& ctx, int i) {
    std::filesystem::create_directories("out");
    char name[64];
    std::snprintf(name, sizeof name, "out/fulgur_%03d.png", i);
    core::write_png(name, ctx.width(), ctx.height(), 4, ctx.read_rgba8());
    return name;
}

// Times of a headless sequence: the stepped leader half-way, then each stroke 1 ms and 6 ms
// after its onset (peak and decay), then evenly over the rest of the flash.
std::vector<double> flash_times(const lightning::FlashProfile& f, double start, int frames) {
    std::vector<double> t = {start + 0.5 * f.leader_duration};
    for (double onset : f.stroke_onset) {
        t.push_back(start + onset + 0.001);
        t.push_back(start + onset + 0.006);
    }
    for (int i = 0; int(t.size()) < frames; ++i) t.push_back(start + f.duration * (i + 0.5) / frames);
    t.resize(std::size_t(frames));
    std::sort(t.begin(), t.end());
    return t;
}

int headless_sequence(scene::Scene s, app::SceneDensity density, const sky::ScenePlan& plan,
                      const std::optional<std::filesystem::path>& fgb, int frames, int w, int h, std::uint64_t seed,
                      std::optional<double> time_of_day) {
    auto ctx = platform::create_headless({.width = w, .height = h});
    const view::StaticSetup setup = app::static_setup(plan, stdout, &density);
    view::StormView view(std::move(s), std::move(density.density), fgb, ctx->get_proc_address(), setup);
    if (time_of_day && plan.sun) {  // the sun moved along its course, solved here
        const sky::SunCourse course = sky::sun_course(*view.scene().sun);
        const scene::Sun sun = course.at(*time_of_day);
        view.set_sun_solve(
            sky::solve_sun(view.scene(), view.density(), view.static_media(), plan.settings, sun.direction));
        view.set_sun(sun);
    }
    std::vector<double> times(std::size_t(frames), 0.0);  // without lightning: the same still scene
    if (view.has_lightning()) {
        const std::size_t strike = view.pipeline().strike_at(0.0, seed);
        times = flash_times(view.pipeline().storm().strike(strike).profile, 0.0, frames);
    }
    const render::Camera cam = view::scene_camera(view.scene().camera, view.density());
    for (int i = 0; i < frames; ++i) {
        const double t = times[std::size_t(i)];
        view::ViewOptions opt;
        opt.settings.frame_index = std::uint32_t(i);
        const view::FrameReport r = view.render(cam, t, w, h, opt);
        ctx->present();
        std::printf("%s  t=%.4f s  %s\n", write_sequence_frame(*ctx, i).c_str(), t,
                    app::timings_json(r, w, h, "fulgur").c_str());
    }
    return 0;
}

const char* kNoDisplay =
    "fulgur: no display available (DISPLAY unset or GLFW cannot open it); rendering %d headless frames into out/ "
    "instead\n";

}  // namespace

int main(int argc, char** argv) {
    app::DemoArgs args;
    if (const std::optional<int> status = app::start(argc, argv, args, app::parse_demo_args, app::demo_usage))
        return *status;
    const std::filesystem::path scene_path = args.scene;
    const bool force_headless = args.headless;
    const int screenshot_after = args.screenshot_after, frames = args.frames, W = args.width, H = args.height;
    const std::optional<std::uint64_t> seed_arg = args.seed;
    const double time_scale = args.time_scale;
    const bool at_peak = args.screenshot_at_peak, solve_direct_at_start = args.solve_direct;
    try {
        scene::Scene s = scene::load_scene(scene_path);
        if (args.camera) s.camera = args.camera;
        app::SceneDensity density = app::load_density(s);
        const sky::ScenePlan plan = app::plan_and_print(s, density.density, stdout);
        const auto fgb = app::bases_for(plan, s, density.density, std::nullopt);
        if (force_headless || !platform::display_available()) {
            if (!force_headless) std::printf(kNoDisplay, frames);
            const std::uint64_t sd = seed_arg.value_or(s.lightning.seed);
            return headless_sequence(std::move(s), std::move(density), plan, fgb, frames, std::min(W, 640),
                                     std::min(H, 360), sd, args.time_of_day);
        }
        app::DemoShell shell(W, H, "Fulgur", screenshot_after);
        shell.show_panels(args.panels);
        const view::StaticSetup setup = app::static_setup(plan, stdout, &density);
        view::StormView view(std::move(s), std::move(density.density), fgb, shell.context().get_proc_address(), setup);
        std::optional<app::TimeOfDay> time_of_day;
        if (view.plan().sun) time_of_day.emplace(view, args.time_of_day);

        // The scene's camera as an orbit the mouse turns; the wheel's range spans 0.4-5 cloud sizes
        // (and the scene's own distance).
        scene::CameraSpec view_spec = view::explicit_orbit(view.scene().camera, view.density());
        const glm::dvec3 extent = view.density().geom.extent();
        const double size = std::max({extent.x, extent.y, extent.z});
        app::Orbit orbit{view_spec.azimuth_deg, view_spec.elevation_deg, *view_spec.distance,
                         std::min(0.4 * size, *view_spec.distance), std::max(5.0 * size, *view_spec.distance)};
        view::ViewOptions opt;
        opt.settings.dither = args.dither;
        opt.settings.temporal = true;  // the march's history: a still view re-marches only what changed in shape
        // The programs the storm's frames will ask for, compiled now rather than at the first
        // flash, move or leader (each a stall of up to half a second on a cold shader cache).
        const double warm_ms =
            view.warm_up(view::scene_camera(view_spec, view.density()), shell.width(), shell.height(), opt);
        std::printf("renderer warmed up in %.0f ms\n", warm_ms);
        std::fflush(stdout);
        const int seed = int(seed_arg.value_or(view.scene().lightning.seed));
        double t = 0.0;
        view::FrameReport rep;
        app::SliceWindow slice;
        // --screenshot-at-peak holds the time 2 ms after the first strike's return stroke.
        double peak_time = 0.2;
        if (view.has_lightning()) {
            const std::size_t first = view.pipeline().strike_at(0.2, std::uint64_t(seed));
            peak_time += view.pipeline().storm().strike(first).profile.stroke_onset.at(0) + 0.002;
        }
        if (args.quality) view.set_quality(scene::quality_preset(*args.quality));
        // The quality section: preset, its costs, the frame's error against a reference.
        app::AccuracyPanel accuracy(view);
        app::DemoPanel panel(view, accuracy, time_of_day ? &*time_of_day : nullptr, seed, time_scale);
        panel.turn(args.orbit_deg_per_s);
        // The view as a scene's "camera" (printed by C and with each screenshot), to 8 significant
        // digits: ~mm at storm distances.
        const auto view_json = [&] { return scene::camera_json(view_spec, 8); };
        while (shell.begin_frame(orbit)) {
            // --solve-direct: ask for the direct solve of the second frame.
            if (solve_direct_at_start && shell.frames() == 1)
                accuracy.request(false);  // frames() counts finished frames
            if (args.static_truth && shell.frames() == 1) accuracy.request_static();
            if (!accuracy.holds_time()) t = at_peak ? peak_time : t + shell.dt() * panel.time_scale();
            // The panels, unless H hid them (Space still strikes).
            bool strike = shell.strike_pressed();
            if (shell.panels_shown()) {
                strike = panel.draw(shell, t, rep, opt);
                // The radiance slice, in its own window at the bottom right.
                slice.draw(view.last_frame(), shell.width(), shell.height());
            }
            panel.apply(t, strike);
            accuracy.update(t, opt);
            // --solve-direct: the screenshot shows its result; --screenshot-at-peak with a
            // per-strike preset: it shows the strike's own light, not the bases' fallback.
            const runtime::Frame* shown = view.last_frame();
            shell.hold_screenshot(accuracy.busy() || (at_peak && shown && shown->strikes_fallback > 0));
            if (time_of_day) {
                time_of_day->update();
                if (time_of_day->busy()) shell.delay_screenshot();  // a screenshot shows the new sun
            }
            opt.settings.frame_index++;
            orbit.turn(panel.turn_rate() * shell.dt());
            view_spec.azimuth_deg = orbit.az;
            view_spec.elevation_deg = orbit.el;
            view_spec.distance = orbit.dist;
            if (shell.camera_pressed() || panel.take_camera_request()) {
                const std::string json = view_json();
                std::printf("camera: %s\n", json.c_str());
                std::fflush(stdout);
                ImGui::SetClipboardText(json.c_str());
            }
            const render::Camera cam = view::scene_camera(view_spec, view.density());
            rep =
                view.render(cam, t, shell.width(), shell.height(), opt, accuracy.shown_field(), accuracy.shown_rain());
            panel.add_frame(rep);
            // A screenshot's view, so that it can be drawn again (fulgur-shot --camera).
            if (shell.end_frame()) std::printf("screenshot camera: %s\n", view_json().c_str());
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur: %s\n", e.what());
        return app::kExitFailure;
    }
    return 0;
}
