// fulgur: the interactive storm demo (GLFW window + Dear ImGui panel). Without a display it
// says so and renders a short headless PNG sequence through OSMesa into out/.
#include "common/cli.h"
#include "common/demo_args.h"
#include "common/view_cli.h"
#include "core/core.h"
#include "demo/accuracy_panel.h"
#include "demo/plots.h"
#include "demo/shell.h"
#include "platform/platform.h"
#include "render/render.h"

#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
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

struct SliceGL {
    void (*GenTextures)(GLsizei, GLuint*);
    void (*BindTexture)(GLenum, GLuint);
    void (*TexParameteri)(GLenum, GLenum, GLint);
    void (*PixelStorei)(GLenum, GLint);
    void (*TexImage2D)(GLenum, GLint, GLint, GLsizei, GLsizei, GLint, GLenum, GLenum, const void*);
};
SliceGL load_slice_gl() {
    SliceGL g{};
    g.GenTextures = reinterpret_cast<decltype(g.GenTextures)>(glfwGetProcAddress("glGenTextures"));
    g.BindTexture = reinterpret_cast<decltype(g.BindTexture)>(glfwGetProcAddress("glBindTexture"));
    g.TexParameteri = reinterpret_cast<decltype(g.TexParameteri)>(glfwGetProcAddress("glTexParameteri"));
    g.PixelStorei = reinterpret_cast<decltype(g.PixelStorei)>(glfwGetProcAddress("glPixelStorei"));
    g.TexImage2D = reinterpret_cast<decltype(g.TexImage2D)>(glfwGetProcAddress("glTexImage2D"));
    if (!g.GenTextures || !g.BindTexture || !g.TexParameteri || !g.PixelStorei || !g.TexImage2D)
        throw core::Error("fulgur", "the window's GL context lacks basic texture functions");
    return g;
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

int headless_sequence(scene::Scene s, core::Grid3<float> density, const sky::ScenePlan& plan,
                      const std::optional<std::filesystem::path>& fgb, int frames, int w, int h, std::uint64_t seed,
                      std::optional<double> time_of_day) {
    auto ctx = platform::create_headless({.width = w, .height = h});
    view::StormView view(std::move(s), std::move(density), fgb, ctx->get_proc_address(),
                         app::static_setup(plan, stdout));
    if (time_of_day && plan.sun) {  // the sun moved along its course, solved here
        const sky::SunCourse course = sky::sun_course(*view.scene().sun);
        const scene::Sun sun = course.at(*time_of_day);
        view.set_sun_solve(sky::solve_sun(view.scene(), view.density(), view.media(), plan.settings, sun.direction));
        view.set_sun(sun);
    }
    std::vector<double> times(std::size_t(frames), 0.0);  // without lightning: the same still scene
    if (view.has_lightning()) {
        const std::size_t strike = view.pipeline().strike_at(0.0, seed);
        times = flash_times(view.pipeline().storm().strike(strike).profile, 0.0, frames);
    }
    const render::Camera cam = view::default_camera(view.density());
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

// The exposure controls: automatic (with eye adaptation: at once toward a flash, over
// seconds back to the night) and its compensation, or a manual exposure starting from the
// last automatic one.
void exposure_panel(render::Settings& st, const view::FrameReport& last, double dt) {
    const bool was_auto = st.auto_exposure;
    ImGui::Checkbox("automatic exposure", &st.auto_exposure);
    if (was_auto && !st.auto_exposure && last.gpu.exposure > 0.0) st.exposure = last.gpu.exposure;
    if (st.auto_exposure) {
        float ev = float(st.exposure_compensation);
        if (ImGui::SliderFloat("compensation (EV)", &ev, -4.0f, 4.0f)) st.exposure_compensation = double(ev);
        ImGui::Text("exposure %.3g (metered %.3g)", last.gpu.exposure, last.gpu.metered_exposure);
        st.previous_exposure = last.gpu.exposure;
        st.adaptation_seconds = dt;
    } else {
        float expo = float(std::log2(st.exposure));
        if (ImGui::SliderFloat("exposure (EV)", &expo, -20.0f, 16.0f)) st.exposure = std::exp2(double(expo));
    }
}

// The time of day: the scene's sun (or moon) moved along its course (sky::SunCourse). A new
// direction is solved on a worker thread (sky::SunResolver, one core: the other keeps
// rendering) while the view keeps showing the field of the last solve; irradiance and colour
// follow the solve that arrives, so what is shown is always one consistent sun.
class TimeOfDay {
public:
    // Keeps references into `view` (scene, density, media): declared after it.
    TimeOfDay(view::StormView& view, std::optional<double> start_hour)
        : view_(view), course_(sky::sun_course(*view.scene().sun)), shown_(course_.scene_hour) {
        resolver_ =
            std::make_unique<sky::SunResolver>(view.scene(), view.density(), view.media(), view.plan().settings, 1);
        hour_ = float(shown_);
        if (start_hour) {
            hour_ = float(std::clamp(*start_hour, course_.first_hour, course_.last_hour));
            request();
        }
    }
    // Takes a finished solve (the newest) and shows it.
    void update() {
        std::optional<sky::SunSolve> r = resolver_->take();
        if (!r) return;
        // The request it answers (the ones before it were skipped); later ones are still coming.
        for (std::size_t i = requests_.size(); i-- > 0;)
            if (requests_[i].second == r->direction) {
                shown_ = requests_[i].first;
                requests_.erase(requests_.begin(), requests_.begin() + std::ptrdiff_t(i) + 1);
                break;
            }
        last_seconds_ = r->seconds;
        double el = 0.0, az = 0.0;
        course_.angles(shown_, el, az);
        std::printf("time of day: %.2f h (elevation %.1f deg, azimuth %.0f deg), solved in %.0f ms\n", shown_, el, az,
                    1e3 * last_seconds_);
        view_.set_sun_solve(std::move(*r));
        view_.set_sun(course_.at(shown_));
    }
    bool busy() const { return resolver_->busy(); }
    // The panel section: the slider, where the sun stands, the re-solve's state.
    void panel() {
        const std::string& name = view_.scene().sun->name;
        ImGui::Text("Time of day (the %s)", name.empty() ? "sun" : name.c_str());
        if (ImGui::SliderFloat("solar time (h)", &hour_, float(course_.first_hour), float(course_.last_hour), "%.2f"))
            request();
        double el = 0.0, az = 0.0;
        course_.angles(shown_, el, az);
        ImGui::Text("shown: %.2f h, elevation %.1f deg, azimuth %.0f deg", shown_, el, az);
        if (busy())
            ImGui::TextUnformatted("solving the new direction (the old light stays shown)...");
        else if (last_seconds_ > 0.0)
            ImGui::Text("last re-solve %.0f ms (lattice + full-resolution transmittance)", 1e3 * last_seconds_);
    }

private:
    void request() {
        const glm::dvec3 d = course_.at(double(hour_)).direction;
        requests_.emplace_back(double(hour_), d);
        resolver_->request(d);
    }
    view::StormView& view_;
    sky::SunCourse course_;
    std::unique_ptr<sky::SunResolver> resolver_;
    std::vector<std::pair<double, glm::dvec3>> requests_;  // not yet shown: hour and direction
    float hour_ = 12.0f;
    double shown_ = 12.0, last_seconds_ = 0.0;
};

// The static light's run-time switches (the scene's effects must call for each).
void static_light_panel(view::ViewOptions& opt, const sky::ScenePlan& plan) {
    ImGui::BeginDisabled(!plan.sun);
    ImGui::Checkbox("sun / moon", &opt.sun);
    ImGui::SameLine();
    ImGui::Checkbox("silver lining (full resolution)", &opt.sun_full_resolution);
    ImGui::EndDisabled();
    ImGui::BeginDisabled(!plan.sky);
    ImGui::Checkbox("sky light", &opt.sky);
    ImGui::EndDisabled();
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
        core::Grid3<float> density = scene::make_density(s);
        const sky::ScenePlan plan = app::plan_and_print(s, density, stdout);
        const auto fgb = app::bases_for(plan, s, density, std::nullopt);
        if (force_headless || !platform::display_available()) {
            if (!force_headless) std::printf(kNoDisplay, frames);
            const std::uint64_t sd = seed_arg.value_or(s.lightning.seed);
            return headless_sequence(std::move(s), std::move(density), plan, fgb, frames, std::min(W, 640),
                                     std::min(H, 360), sd, args.time_of_day);
        }
        app::DemoShell shell(W, H, "Fulgur", screenshot_after);
        view::StormView view(std::move(s), std::move(density), fgb, shell.context().get_proc_address(),
                             app::static_setup(plan, stdout));
        const bool has_lightning = view.has_lightning();
        const bool separate = has_lightning ? view.bases().has_multiple() : view.scene().effects.multiple_scattering;
        std::optional<TimeOfDay> time_of_day;
        if (view.plan().sun) time_of_day.emplace(view, args.time_of_day);

        app::Orbit orbit{-90, 6, 1.1, 0.4, 5.0};  // distance as a multiple of the cloud size
        view::ViewOptions opt;
        opt.settings.dither = args.dither;
        float rate = float(view.scene().lightning.schedule.strike_rate);
        int seed = int(seed_arg.value_or(view.scene().lightning.seed));
        bool autos = rate > 0;
        double t = 0.0;
        view::FrameReport rep;
        // The few GL calls of the slice image, through the window's get-proc-address (the
        // process also links OSMesa, whose gl* symbols must not be called on a GLX context).
        const SliceGL gl = load_slice_gl();
        GLuint slice_tex = 0;
        gl.GenTextures(1, &slice_tex);
        // --screenshot-at-peak holds the time 2 ms after the first strike's return stroke.
        double peak_time = 0.2;
        if (has_lightning) {
            const std::size_t first = view.pipeline().strike_at(0.2, std::uint64_t(seed));
            peak_time += view.pipeline().storm().strike(first).profile.stroke_onset.at(0) + 0.002;
        }
        float slow = float(time_scale);
        lightning::LightningParams lp = view.scene().lightning;
        // The slider holds a float: compare against what it can represent, or the first frame
        // would see a "changed" rate and rebuild the storm (dropping the first strike).
        lp.schedule.strike_rate = autos ? double(rate) : 0.0;
        bool shape_changed = false;
        if (args.quality) view.set_quality(scene::quality_preset(*args.quality));
        // The quality section: preset, its costs, the frame's error against a reference.
        app::AccuracyPanel accuracy(view);
        app::FrameTimePlots frame_plots;
        app::FlashPlot flash_plot;
        while (shell.begin_frame(orbit)) {
            // --solve-direct: ask for the direct solve of the second frame.
            if (solve_direct_at_start && shell.frames() == 1)
                accuracy.request(false);  // frames() counts finished frames
            if (!accuracy.holds_time()) t = at_peak ? peak_time : t + shell.dt() * double(slow);
            bool strike = shell.strike_pressed();
            ImGui::SetNextWindowPos({10, 10}, ImGuiCond_FirstUseEver);
            ImGui::SetNextWindowSize({430, 0}, ImGuiCond_FirstUseEver);
            ImGui::Begin("Fulgur", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
            ImGui::Text("%.1f fps  (%.1f ms frame)", shell.fps(), rep.wall_ms);
            ImGui::Separator();
            ImGui::BeginDisabled(!has_lightning);
            ImGui::TextUnformatted(has_lightning ? "Lightning" : "Lightning (the scene has none)");
            ImGui::InputInt("seed", &seed);
            if (ImGui::Button("Strike now")) strike = true;
            ImGui::Checkbox("automatic strikes", &autos);
            ImGui::SliderFloat("rate (1/s)", &rate, 0.01f, 2.0f);
            ImGui::SliderFloat("time scale", &slow, 0.01f, 1.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
            if (ImGui::IsItemHovered())
                ImGui::SetTooltip("storm seconds per wall second (slow motion: a flash decays in ~12 ms)");
            if (has_lightning) flash_plot.draw(view.pipeline().storm(), t);
            {
                lightning::BoltParams& b = lp.bolt;
                int kind = int(b.kind);
                bool changed = ImGui::Combo("kind", &kind, "cloud to ground\0intra-cloud\0cloud to cloud\0");
                b.kind = lightning::Kind(kind);
                float bp = float(b.branch_probability), sp = float(b.angle_spread_deg),
                      ie = float(std::log10(b.intensity));
                changed |= ImGui::SliderFloat("branch probability", &bp, 0.0f, 0.6f);
                changed |= ImGui::SliderFloat("angle spread (deg)", &sp, 0.0f, 40.0f);
                changed |= ImGui::SliderFloat("intensity (log10 W/sr/m)", &ie, 3.0f, 7.0f);
                b.branch_probability = bp, b.angle_spread_deg = sp, b.intensity = std::pow(10.0, double(ie));
                if (changed) shape_changed = true;
            }
            ImGui::EndDisabled();
            ImGui::Separator();
            ImGui::TextUnformatted("Light");
            ImGui::BeginDisabled(!separate);
            ImGui::Checkbox("single scattering", &opt.components.single);
            ImGui::Checkbox("multiple scattering", &opt.components.multiple);
            ImGui::EndDisabled();
            if (!separate && ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
                ImGui::SetTooltip("this bake has no separate multiple-scattering component");
            ImGui::Checkbox("glow", &opt.settings.glow);
            ImGui::Checkbox("bolt", &opt.settings.bolt);
            ImGui::Checkbox("ground", &opt.settings.ground);
            static_light_panel(opt, view.plan());
            exposure_panel(opt.settings, rep, shell.dt());
            float scale = float(opt.settings.internal_scale);
            if (ImGui::SliderFloat("internal scale", &scale, 0.25f, 1.0f)) opt.settings.internal_scale = scale;
            if (time_of_day) {
                ImGui::Separator();
                time_of_day->panel();
            }
            ImGui::Separator();
            accuracy.draw(rep);
            ImGui::Separator();
            ImGui::TextUnformatted("Frame times, last 240 frames (ms)");
            frame_plots.draw();
            if (ImGui::TreeNode("this frame's stages")) {
                ImGui::Text("bolt %.2f  sources %.2f  splat %.2f", rep.stages.bolt, rep.stages.sources,
                            rep.stages.splat);
                ImGui::Text("accumulate %.2f  inverse Haar %.2f  strike light %.2f", rep.stages.accumulate,
                            rep.stages.inverse_haar, rep.stages.strike_light);
                ImGui::Text("upload %.2f  ray march %.2f  GPU total %.2f", rep.gpu.wall.upload, rep.gpu.wall.march,
                            rep.gpu.wall.total);
                ImGui::TreePop();
            }
            ImGui::End();
            // Cross-section of the radiance S (paper Fig. 6(b,d)), in its own window at the
            // bottom right (the panel fills a 720-pixel-high window already).
            const runtime::Frame* f = view.last_frame();
            if (f && f->lit && !f->radiance.values.empty()) {
                const core::GridGeometry& g = f->radiance.geometry;
                const std::vector<float>& v = f->radiance.values[0];
                // The x-z slice through the brightest cell (where the bolt lights the cloud).
                const int j = g.unindex(std::size_t(std::max_element(v.begin(), v.end()) - v.begin())).y;
                float vmax = 0;
                for (int k = 0; k < g.dims.z; ++k)
                    for (int i = 0; i < g.dims.x; ++i) vmax = std::max(vmax, v[g.index(i, j, k)]);
                std::vector<std::uint8_t> img(std::size_t(g.dims.x) * g.dims.z * 4);
                for (int k = 0; k < g.dims.z; ++k)
                    for (int i = 0; i < g.dims.x; ++i) {
                        std::uint8_t* px = &img[(std::size_t(g.dims.z - 1 - k) * g.dims.x + i) * 4];
                        core::pseudo_colour(vmax > 0 ? std::sqrt(v[g.index(i, j, k)] / vmax) : 0.0, px);
                        px[3] = 255;
                    }
                gl.BindTexture(GL_TEXTURE_2D, slice_tex);
                gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
                gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
                gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
                gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, g.dims.x, g.dims.z, 0, GL_RGBA, GL_UNSIGNED_BYTE, img.data());
                const float wpx = 240.0f;
                ImGui::SetNextWindowPos({float(shell.width()) - 10.0f, float(shell.height()) - 10.0f},
                                        ImGuiCond_FirstUseEver, {1.0f, 1.0f});
                ImGui::Begin("S: x-z slice through its maximum", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
                ImGui::Image((ImTextureID)(intptr_t)slice_tex, {wpx, wpx * g.dims.z / float(g.dims.x)});
                if (ImGui::IsItemHovered())
                    ImGui::SetTooltip(
                        "the reconstructed source function S (first direction), square-root scale,\n"
                        "normalized to the slice's maximum: where the bolt lights the cloud");
                ImGui::End();
            }

            const double want_rate = autos ? double(rate) : 0.0;
            if (has_lightning && (shape_changed || want_rate != lp.schedule.strike_rate)) {
                // Bolt shape / schedule changed: new storm (bolts regenerate), same bake.
                lp.schedule.strike_rate = want_rate;
                lp.schedule.first_strike = t + 0.5;
                lp.seed = std::uint64_t(seed);
                view.set_lightning(lp);
                shape_changed = false;
                accuracy.reset();
            }
            if (strike && has_lightning) {
                view.pipeline().strike_at(t, std::uint64_t(seed++));
                accuracy.reset();  // the reference belongs to one frame
            }
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
            const render::Camera cam = view::default_camera(view.density(), orbit.az, orbit.el, orbit.dist);
            rep = view.render(cam, t, shell.width(), shell.height(), opt, accuracy.shown_field());
            frame_plots.add(rep);
            shell.end_frame();
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur: %s\n", e.what());
        return app::kExitFailure;
    }
    return 0;
}
