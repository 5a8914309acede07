// fulgur-minimal: the engine embedded from its installed package. Loads a scene, bakes its
// virtual lights when the .fgb beside it is missing or stale, schedules one lightning strike
// and renders two frames into PNGs: before the strike and at its return stroke. Then the same
// instants as a game would draw them (host_terrain.h): its own terrain in its own HDR target
// and camera matrices, lit by the flash's point lights, the storm composited into that target
// (render_into_host: the terrain's depth hides what is behind it), its own tone map.
//
// usage: fulgur-minimal SCENE.json OUT_PREFIX
//   writes OUT_PREFIX_before.png, OUT_PREFIX_flash.png (Fulgur's own frames) and OUT_PREFIX_host.png
//   (the game's frame at the return stroke), 320x180. Prints the mean brightness of the frames;
//   exits 1 if the flash does not light the image or the game's mountains behind the storm, or if
//   the channel shows through the game's ridge in front of it.
#include "host_terrain.h"

#include <fulgur/core/core.h>
#include <fulgur/scene/scene.h>
#include <fulgur/sky/sky.h>
#include <fulgur/view/view.h>

#include <GL/osmesa.h>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
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

        // ---- The game's frame at the return stroke. The flash at that instant as point lights for
        // its own surfaces, in the scene's flash colour.
        std::vector<FlashLight> lights;
        for (const render::Renderer::FlashLight& l : storm.flash_lights(times[1], 6))
            lights.push_back({glm::vec3(l.position), glm::vec3(l.intensity * storm.scene().lightning_colour)});
        if (lights.empty()) throw std::runtime_error("no lit channel at the return stroke");
        const core::GridGeometry& g = storm.density().geom;
        HostWorld world(kWidth, kHeight,
                        {camera.position, g.origin + 0.5 * g.extent(), storm.flash_lights(times[1], 1)[0].position,
                         0.5 * std::max(g.extent().x, g.extent().y)});
        // Its own camera matrices for the scene's view, its terrain (first without the flash, to see
        // what the flash adds), then the storm composited into its target up to the terrain's depth.
        const glm::dmat4 view_matrix = glm::lookAt(camera.position, camera.target, camera.up);
        const glm::dmat4 projection =
            glm::perspective(glm::radians(camera.vertical_fov_deg), double(kWidth) / kHeight, 10.0, 2e5);
        world.draw_terrain(glm::mat4(projection * view_matrix), {});
        const std::vector<float> dark = world.read();
        world.draw_terrain(glm::mat4(projection * view_matrix), lights);
        const std::vector<float> lit = world.read();
        // One ray-march ray per pixel: the march reads the terrain's depth per ray, so at the default
        // half resolution the cloud behind would bleed a pixel into the ridge's silhouette.
        view::ViewOptions host_options = options;
        host_options.settings.internal_scale = 1.0;
        storm.render_into_host({view_matrix, projection, world.depth_texture()}, times[1], kWidth, kHeight,
                               host_options);
        const std::vector<float> hdr = world.read();  // alpha: what the terrain is there (kept by Fulgur)

        // Its tone map: the exposure that puts the frame's 99th percentile at 3/4 of white.
        std::vector<float> lum;
        for (std::size_t i = 0; i < hdr.size(); i += 4)
            lum.push_back(0.2126f * hdr[i] + 0.7152f * hdr[i + 1] + 0.0722f * hdr[i + 2]);
        std::nth_element(lum.begin(), lum.begin() + std::ptrdiff_t(lum.size() * 99 / 100), lum.end());
        const float exposure = 3.0f / lum[lum.size() * 99 / 100];
        world.tone_map(exposure);
        const double host_mean = gl.save(prefix + "_host.png");

        // The flash lights the range behind the storm: the terrain's mean there, without and with it,
        // as displayed (exposure x / (1 + exposure x), 8-bit).
        auto shown = [&](float x) { return 255.0 * std::pow(exposure * x / (1.0 + exposure * x), 1.0 / 2.2); };
        double range[2] = {0.0, 0.0};
        int range_px = 0;
        for (std::size_t i = 0; i < lit.size(); i += 4)
            if (lit[i + 3] == HostWorld::kRange) {
                range[0] += shown(dark[i + 1]);
                range[1] += shown(lit[i + 1]);
                ++range_px;
            }
        // The ridge hides the channel where it crosses it: the frame's pixels on the channel's
        // projection, where the ridge covers it and where nothing does (the brightest of each).
        double covered = 0.0, open = 0.0;
        for (const lightning::LitSegment& seg : storm.last_frame()->segments)
            for (double u = 0.0; u <= 1.0; u += 0.05) {
                const glm::dvec4 c = projection * view_matrix * glm::dvec4(seg.a + u * (seg.b - seg.a), 1.0);
                const int x = int((c.x / c.w * 0.5 + 0.5) * kWidth), y = int((c.y / c.w * 0.5 + 0.5) * kHeight);
                if (c.w <= 0.0 || x < 0 || y < 0 || x >= kWidth || y >= kHeight) continue;
                const std::size_t i = (std::size_t(y) * kWidth + std::size_t(x)) * 4;
                if (hdr[i + 3] == HostWorld::kRidge) covered = std::max(covered, double(hdr[i + 1]));
                if (hdr[i + 3] == HostWorld::kSky || hdr[i + 3] == HostWorld::kRange)
                    open = std::max(open, double(hdr[i + 1]));
            }
        std::printf(
            "%s_host.png: exposure %.3g, mean brightness %.2f / 255; the range behind the storm %.1f -> %.1f / 255 "
            "in the flash; the channel %.3g, behind the ridge %.3g W m^-2 sr^-1\n",
            prefix.c_str(), exposure, host_mean, range[0] / std::max(range_px, 1), range[1] / std::max(range_px, 1),
            open, covered);
        if (range_px == 0 || !(range[1] > 2.0 * range[0] && range[1] > range[0] + 4.0 * range_px)) {
            std::fprintf(stderr, "the flash does not light the mountains behind the storm\n");
            return 1;
        }
        if (!(open > 0.0 && covered > 0.0) || covered >= 0.1 * open) {
            std::fprintf(stderr, "the ridge does not hide the channel where it crosses it\n");
            return 1;
        }
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur-minimal: %s\n", e.what());
        return 1;
    }
}
