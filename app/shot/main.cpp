// fulgur-shot: one frame of a scene's storm, headless (OSMesa), to PNG; timings as JSON.
#include "common/shot_args.h"
#include "common/storm_view.h"
#include "platform/platform.h"

#include <cmath>
#include <vector>
#include <cstdio>
#include <iostream>

using namespace fulgur;

int main(int argc, char** argv) {
    app::ShotArgs a;
    try {
        a = app::parse_shot_args(std::vector<std::string>(argv + 1, argv + argc));
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 2;
    }
    if (a.help) {
        std::fputs(app::shot_usage().c_str(), stdout);
        return 0;
    }
    try {
        scene::Scene s = scene::load_scene(a.scene);
        core::Grid3<float> density = scene::make_density(s);
        const auto fgb = app::ensure_baked(s, density, a.fgb, true);
        auto ctx = platform::create_headless({.width = a.width, .height = a.height});
        app::StormView view(std::move(s), std::move(density), fgb, ctx->get_proc_address());
        lightning::LightningParams lp = view.scene().lightning;
        lp.schedule.strike_rate = 0.0;  // only the requested strike (after the bake check: same .fgb as the demo)
        view.set_lightning(lp);
        const std::size_t strike = view.pipeline().strike_at(0.0, a.seed);
        const double t =
            a.time + (a.time_after_return_stroke ? view.pipeline().storm().strike(strike).profile.stroke_onset.at(0) : 0.0);
        app::ViewOptions opt;
        opt.settings.exposure *= std::exp2(a.exposure_ev);
        const render::Camera cam = app::default_camera(view.density());
        // Medians over --repeat frames: the first one also compiles shaders and uploads the
        // density; the run time rebuilds the same frame each time (same strike, same t).
        std::vector<app::FrameReport> reps;
        for (int k = 0; k < a.repeat; ++k) {
            opt.settings.frame_index = std::uint32_t(k);
            reps.push_back(view.render(cam, t, a.width, a.height, opt));
        }
        app::FrameReport r = reps.back();
        if (reps.size() > 1) r = app::median_report(reps);
        ctx->present();
        const auto px = ctx->read_rgba8();
        core::write_png(a.output, a.width, a.height, 4, px);
        std::cout << app::timings_json(r, a.width, a.height) << std::endl;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur-shot: %s\n", e.what());
        return 1;
    }
    return 0;
}
