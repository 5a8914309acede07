// fulgur-minimal: the engine embedded from its installed package. Loads a scene, bakes its
// virtual lights when the .fgb beside it is missing or stale, schedules one lightning strike
// and renders two frames into PNGs: before the strike and at its return stroke.
//
// usage: fulgur-minimal SCENE.json OUT_PREFIX   (writes OUT_PREFIX_before.png, OUT_PREFIX_flash.png, 320x180)
// Prints the mean brightness of both frames; exits 1 if the flash does not light the image.
#include <fulgur/core/core.h>
#include <fulgur/scene/scene.h>
#include <fulgur/sky/sky.h>
#include <fulgur/view/view.h>

#include <GL/osmesa.h>

#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

using namespace fulgur;

namespace {

constexpr int kWidth = 320, kHeight = 180;

// The game's side: an off-screen GL 4.5 core context drawing into `pixels` (bottom row first).
struct OffscreenContext {
    OSMesaContext ctx = nullptr;
    std::vector<unsigned char> pixels = std::vector<unsigned char>(std::size_t(kWidth) * kHeight * 4);
    OffscreenContext() {
        const int attribs[] = {OSMESA_FORMAT,
                               OSMESA_RGBA,
                               OSMESA_DEPTH_BITS,
                               24,
                               OSMESA_PROFILE,
                               OSMESA_CORE_PROFILE,
                               OSMESA_CONTEXT_MAJOR_VERSION,
                               4,
                               OSMESA_CONTEXT_MINOR_VERSION,
                               5,
                               0};
        ctx = OSMesaCreateContextAttribs(attribs, nullptr);
        if (!ctx || !OSMesaMakeCurrent(ctx, pixels.data(), GL_UNSIGNED_BYTE, kWidth, kHeight))
            throw std::runtime_error("OSMesa: no GL 4.5 core context");
    }
    ~OffscreenContext() { OSMesaDestroyContext(ctx); }
    // Finishes the frame and writes it as a PNG (top row first); returns its mean brightness.
    double save(const std::string& path) {
        reinterpret_cast<void (*)()>(OSMesaGetProcAddress("glFinish"))();
        std::vector<unsigned char> rgb(std::size_t(kWidth) * kHeight * 3);
        double sum = 0.0;
        for (int y = 0; y < kHeight; ++y)
            for (int x = 0; x < kWidth; ++x)
                for (int c = 0; c < 3; ++c) {
                    const unsigned char v = pixels[(std::size_t(kHeight - 1 - y) * kWidth + x) * 4 + c];
                    rgb[(std::size_t(y) * kWidth + x) * 3 + c] = v;
                    sum += v;
                }
        core::write_png(path, kWidth, kHeight, 3, rgb);
        return sum / double(rgb.size());
    }
};

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: %s SCENE.json OUT_PREFIX\n", argv[0]);
        return 2;
    }
    try {
        scene::Scene s = scene::load_scene(argv[1]);
        core::Grid3<float> density = scene::make_density(s);
        bake::PlanOptions po;
        po.estimate = false;  // the plan's decisions, without timing sample lights
        const sky::ScenePlan plan = sky::plan_scene(s, density, po);
        const auto fgb = view::bases_for(plan, s, density, std::nullopt, {},
                                         [](const std::filesystem::path& f, const std::string& why) {
                                             std::printf("baking %s: %s\n", f.string().c_str(), why.c_str());
                                         });
        OffscreenContext gl;
        view::StaticSetup setup;
        setup.shader_dir = FULGUR_MINIMAL_SHADERS;
        view::StormView storm(std::move(s), std::move(density), fgb, &OSMesaGetProcAddress, setup);
        if (!storm.has_lightning()) throw std::runtime_error(std::string(argv[1]) + ": the scene has no lightning");

        // One strike at t = 1 s (seed 7), no others: the frames are its own.
        lightning::LightningParams lp = storm.scene().lightning;
        lp.schedule.strike_rate = 0.0;
        storm.set_lightning(lp);
        const std::size_t strike = storm.pipeline().strike_at(1.0, 7);
        const double stroke =
            storm.pipeline().storm().strike(strike).profile.stroke_onset.at(0);  // after the strike starts

        const render::Camera camera = view::scene_camera(storm.scene().camera, storm.density());  // the scene's view
        view::ViewOptions options;
        options.wait_for_strikes = true;  // offline frames: the preset's own light, never its fallback
        const std::string prefix = argv[2];
        double mean[2];
        const double times[2] = {0.5, 1.0 + stroke + 0.002};  // before the strike; at its return stroke
        for (int k = 0; k < 2; ++k) {
            const view::FrameReport r = storm.render(camera, times[k], kWidth, kHeight, options);
            const std::string path = prefix + (k == 0 ? "_before.png" : "_flash.png");
            mean[k] = gl.save(path);
            std::printf("%s: t = %.3f s, lit %s, %.2f ms, mean brightness %.2f / 255\n", path.c_str(), times[k],
                        r.lit ? "yes" : "no", r.wall_ms, mean[k]);
        }
        if (!(mean[1] > mean[0])) {
            std::fprintf(stderr, "the flash does not light the frame (%.2f vs %.2f)\n", mean[1], mean[0]);
            return 1;
        }
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur-minimal: %s\n", e.what());
        return 1;
    }
}
