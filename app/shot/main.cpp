// fulgur-shot: one frame of a scene's storm, headless (OSMesa), to PNG; timings as JSON.
#include "common/exr_image.h"
#include "common/image_compare.h"
#include "common/lighting_vdb.h"
#include "common/shot_args.h"
#include "common/tool_start.h"
#include "common/view_cli.h"
#include "platform/platform.h"
#include "shot/blender_export.h"
#include "view/linear_frame.h"

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <optional>
#include <vector>

using namespace fulgur;

namespace {

// The flash's light a render is given in place of its frame's (view::StormView::render's
// `source` and `rain_source`): S, and the light of orders >= 2 at the rain (null or empty: the
// channel alone lights the rain). No S: the frame's own light.
struct GivenLight {
    const transport::SourceField* source = nullptr;
    const transport::SourceField* rain = nullptr;
};

// Relative L2 of `field` against `reference` over the cloud voxels, every direction.
double field_error(view::StormView& view, const transport::SourceField& field,
                   const transport::SourceField& reference) {
    const std::vector<float>& density = view.media().lighting.density.data;
    core::RelativeL2 e;
    for (std::size_t i = 0; i < reference.data.size(); ++i)
        if (density[i % density.size()] > 0.0f) e.add(double(field.data[i]), double(reference.data[i]));
    return e.value();
}

// --since-known: the frame an unscheduled strike shows MS ms after it became known, all
// directions, as a field the renders show; the per-strike work is stopped there. Prints what
// the frames cost meanwhile and how the strike was lit as JSON. `rain` gets the frame's light at
// the rain then (left empty where it has none).
transport::SourceField since_known_field(view::StormView& view, double t, const view::ViewOptions& opt,
                                         const app::ShotArgs& a, transport::SourceField& rain) {
    runtime::FramePipeline& p = view.pipeline();
    runtime::ReconstructOptions ro;
    ro.components = opt.components;
    runtime::SinceKnown seen;
    const runtime::Frame& f = runtime::build_since_known(p, t, *a.since_known_ms, {}, ro, &seen, a.since_leader);
    if (runtime::InstantStrikes* is = p.instant_strikes()) is->set_paused(true);
    if (runtime::StrikeSolver* ss = p.strike_solver()) ss->set_paused(true);
    transport::SourceField field = f.lit ? runtime::every_direction(f.radiance)
                                         : transport::SourceField(view.bases().lighting(), view.bases().directions());
    if (f.lit && !f.rain.values.empty()) rain = runtime::every_direction(f.rain);  // the rain's light as shown then
    std::printf(
        "{\"name\":\"fulgur-shot-since-known\",\"quality\":\"%s\",\"since_known_ms\":%.4g,"
        "\"triggered_at_leader_start\":%s,\"instant_way\":%s,\"frames_meanwhile\":%d,"
        "\"frame_ms_median\":%.4g,\"frame_ms_max\":%.4g,\"strikes_solved\":%zu,\"strikes_fallback\":%zu,"
        "\"instant_weight\":%.4g}\n",
        std::string(scene::to_string(p.quality().preset)).c_str(), *a.since_known_ms, a.since_leader ? "true" : "false",
        p.instant_strikes() ? "true" : "false", seen.frames, seen.median_frame_ms, seen.max_frame_ms, f.strikes_solved,
        f.strikes_fallback, f.instant_weight);
    std::fflush(stdout);
    return field;
}

// The quality the frame is lit with: --quality's preset, else the scene's.
scene::Quality shot_quality(const scene::Scene& s, const app::ShotArgs& a) {
    return a.quality ? scene::quality_preset(*a.quality) : s.quality;
}

// `q` keeping its solved strikes on the lighting grid refined by `refine` (--strike-grid), after
// the checks the scene file's "grid": "transport" gets.
scene::Quality strike_grid_quality(const scene::Scene& s, scene::Quality q, int refine) {
    using P = scene::Quality::Preset;
    if (q.preset == P::Paper || q.preset == P::Instant)
        throw core::Error("--strike-grid", "the " + std::string(scene::to_string(q.preset)) +
                                               " preset keeps no solved strike's light; use a preset that solves "
                                               "strikes ahead (hybrid, per_strike, per_strike_mc, reference)");
    if (s.lighting_downsample % refine != 0)
        throw core::Error("--strike-grid", std::to_string(refine) + " must divide the scene's lighting.downsample (" +
                                               std::to_string(s.lighting_downsample) + ")");
    q.keep_transport_grid = true;
    q.refine = std::max(q.refine, refine);
    return q;
}

// `q` with its solved strikes tallied toward the camera (--strike-toward-camera), after the
// check the scene file's "directions": "camera" gets.
scene::Quality strike_toward_quality(scene::Quality q) {
    q.toward_camera = true;
    if (const std::string why = scene::toward_camera_problem(q); !why.empty())
        throw core::Error("--strike-toward-camera", why);
    return q;
}

// The quality the shot's options make of `q` (--strike-grid, --strike-toward-camera).
scene::Quality shot_options_quality(const scene::Scene& s, scene::Quality q, const app::ShotArgs& a) {
    if (a.strike_grid > 0) q = strike_grid_quality(s, q, a.strike_grid);
    if (a.strike_toward_camera) q = strike_toward_quality(q);
    return q;
}

void write_frame_exr(view::StormView& view, const render::Camera& cam, double t, const view::ViewOptions& opt,
                     const app::ShotArgs& a, GivenLight shown, double shown_exposure, const std::filesystem::path& out,
                     const std::string& lit_by);

// What --reference writes besides its JSON line: the reference frame's image (and with --exr its
// radiance, OUT_reference.exr), the difference of the cloud's radiance (march buffer: no glow,
// no jitter) between the shown field and the reference, and the three side by side.
// `show_reference` / `show_basis` make the view light the frame by the reference or by what was
// shown (before each render).
app::RadianceComparison reference_images(view::StormView& view, platform::Context* ctx, const render::Camera& cam,
                                         double t, const view::ViewOptions& opt, const app::ShotArgs& a,
                                         const std::vector<std::uint8_t>& shown_basis, GivenLight shown_light,
                                         GivenLight reference_light, const std::function<void()>& show_reference,
                                         const std::function<void()>& show_basis, app::DisplayDifference& shown, int& w,
                                         int& h) {
    show_reference();
    const double ref_exposure =
        view.render(cam, t, a.width, a.height, opt, reference_light.source, reference_light.rain).gpu.exposure;
    ctx->present();
    const std::vector<std::uint8_t> shown_ref = ctx->read_rgba8();
    core::write_png(*a.reference, a.width, a.height, 4, shown_ref);
    if (a.exr)
        write_frame_exr(view, cam, t, opt, a, reference_light, ref_exposure, app::reference_exr_path(*a.exr),
                        a.against == "static" ? ", its static light by the truth (--against static)"
                                              : ", lit by the reference (--against " + a.against + ")");
    shown = app::compare_display(shown_basis, shown_ref);

    // The cloud alone (no glow in the march buffer, no jitter), once per field.
    view::ViewOptions metric = opt;
    metric.settings.glow = false;
    metric.settings.jitter = false;
    show_basis();
    view.render(cam, t, a.width, a.height, metric, shown_light.source, shown_light.rain);
    const std::vector<float> basis = view.renderer().read_march(w, h);
    show_reference();
    view.render(cam, t, a.width, a.height, metric, reference_light.source, reference_light.rain);
    const std::vector<float> ref = view.renderer().read_march(w, h);
    show_basis();
    const app::RadianceComparison c = app::compare_radiance(basis, ref);
    const std::vector<std::uint8_t> diff_px = app::difference_image(basis, ref);
    core::write_png(app::reference_diff_path(*a.reference), w, h, 4, diff_px);
    // Side by side for a quick look: basis | reference | difference (nearest-upsampled).
    const int W = a.width, H = a.height;
    std::vector<std::uint8_t> trio(std::size_t(3 * W) * std::size_t(H) * 4);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int ch = 0; ch < 4; ++ch) {
                const std::size_t src = (std::size_t(y) * std::size_t(W) + std::size_t(x)) * 4 + std::size_t(ch);
                const std::size_t row = std::size_t(y) * std::size_t(3 * W);
                trio[(row + std::size_t(x)) * 4 + std::size_t(ch)] = shown_basis[src];
                trio[(row + std::size_t(W + x)) * 4 + std::size_t(ch)] = shown_ref[src];
                const std::size_t dx = std::size_t(x) * std::size_t(w) / std::size_t(W);
                const std::size_t dy = std::size_t(y) * std::size_t(h) / std::size_t(H);
                trio[(row + std::size_t(2 * W + x)) * 4 + std::size_t(ch)] =
                    diff_px[(dy * std::size_t(w) + dx) * 4 + std::size_t(ch)];
            }
    core::write_png(app::reference_compare_path(*a.reference), 3 * W, H, 4, trio);
    return c;
}

// --reference: the same frame lit by the truth (or the direct solve), its difference image and the errors
// (S over the cloud; the cloud's in-scattered radiance in the image) and times as JSON.
void render_reference(view::StormView& view, platform::Context* ctx, const render::Camera& cam, double t,
                      const view::ViewOptions& opt, const app::ShotArgs& a,
                      const std::vector<std::uint8_t>& shown_basis, GivenLight shown_light) {
    const transport::SourceField* shown_field = shown_light.source;
    transport::SourceField direct, direct_rain;
    double solve_s = 0.0, frame_ms = 0.0;
    transport::MonteCarloResult::Noise noise;
    if (a.against == "truth") {
        runtime::TruthOptions to;
        to.paths = a.truth_paths;
        to.seed = a.seed;
        view::StormView::TruthSolve solved = view.solve_truth(t, opt.components, to, !shown_field);
        direct = std::move(solved.field);
        direct_rain = std::move(solved.rain);
        solve_s = solved.seconds;
        frame_ms = solved.basis_ms;
        noise = solved.noise;
    } else {
        view::StormView::DirectSolve solved = view.solve_direct(t, opt.components, !shown_field);
        direct = std::move(solved.field);
        solve_s = solved.seconds;
        frame_ms = solved.basis_ms;
    }
    // The basis frame's figures now, for all directions (the solve's counterpart): the
    // renders below rebuild the frame for the view's directions only.
    const runtime::Frame& f = *view.last_frame();
    const bool lit = f.lit;
    const std::size_t sources = f.sources.size(), active = f.weights.active.size();
    const double s_err = shown_field ? field_error(view, *shown_field, direct) : view.reconstruction_error(direct);

    app::DisplayDifference shown;
    const auto nothing = [] {};
    int w = 0, h = 0;
    const app::RadianceComparison c = reference_images(view, ctx, cam, t, opt, a, shown_basis, shown_light,
                                                       {&direct, &direct_rain}, nothing, nothing, shown, w, h);
    std::printf(
        "{\"name\":\"fulgur-shot-reference\",\"against\":\"%s\",\"quality\":\"%s\",\"lit\":%s,"
        "\"sources\":%zu,\"active_lights\":%zu,\"reference_noise\":%.4g,"
        "\"reference_s\":%.4g,\"frame_ms_all_directions\":%.4g,\"speedup\":%.4g,"
        "\"source_rel_l2\":%.4g,\"image_rel_l2\":%.4g,\"image_max_difference\":%.4g,"
        "\"image_fraction_over_10pct\":%.4g,\"image_lit_pixels\":%zu,\"image_width\":%d,\"image_height\":%d,"
        "\"shown_mean_levels\":%.4g,\"shown_fraction_over_25_levels\":%.4g}\n",
        a.against.c_str(), std::string(scene::to_string(view.pipeline().quality().preset)).c_str(),
        lit ? "true" : "false", sources, active, noise.total, solve_s, frame_ms,
        frame_ms > 0.0 ? solve_s * 1e3 / frame_ms : 0.0, s_err, c.relative_l2, c.max_difference, c.fraction_over,
        c.lit_pixels, w, h, shown.mean_levels, shown.fraction_over);
    std::fflush(stdout);
}

// --reference --against static: the same frame with its static light (sun or moon, sky) by the
// truth (sky::static_truth) in place of the scene's solves; the lightning is the frame's in
// both. Errors of the static light's S in colour (single, multiple, total) over the cloud and
// of the cloud's radiance in the image, as JSON.
void render_static_reference(view::StormView& view, platform::Context* ctx, const render::Camera& cam, double t,
                             const view::ViewOptions& opt, const app::ShotArgs& a,
                             const std::vector<std::uint8_t>& shown_basis, GivenLight shown_light) {
    sky::TruthOptions to;
    to.paths = a.truth_paths;
    to.seed = a.seed;
    view::StormView::StaticTruthSolve truth = view.solve_static_truth(to);
    const sky::StaticLight solved = view.static_light();
    double noise = 0.0;
    for (const transport::MonteCarloResult::Noise& n : truth.noise) noise = std::max(noise, n.total);
    sky::ComposeOptions co;
    co.sun = opt.sun;
    co.sky = opt.sky;
    double err[3] = {};
    for (int part = 0; part < 3; ++part) {
        co.single = part != 1;
        co.multiple = part != 0;
        const sky::ColourField ref = view.static_colour(co, &truth.light);
        err[part] = sky::colour_error(view.static_colour(co), ref, view.static_media().lighting.density.data);
    }
    app::DisplayDifference shown;
    int w = 0, h = 0;
    const app::RadianceComparison c = reference_images(
        view, ctx, cam, t, opt, a, shown_basis, shown_light, shown_light, [&] { view.set_static_light(truth.light); },
        [&] { view.set_static_light(solved); }, shown, w, h);
    std::printf(
        "{\"name\":\"fulgur-shot-static-reference\",\"against\":\"static\",\"sun\":%s,\"sky\":%s,"
        "\"reference_noise\":%.4g,\"reference_s\":%.4g,\"single_rel_l2\":%.4g,\"multiple_rel_l2\":%.4g,"
        "\"source_rel_l2\":%.4g,\"image_rel_l2\":%.4g,\"image_max_difference\":%.4g,"
        "\"image_fraction_over_10pct\":%.4g,\"image_lit_pixels\":%zu,"
        "\"shown_mean_levels\":%.4g,\"shown_fraction_over_25_levels\":%.4g}\n",
        solved.sun ? "true" : "false", solved.sky ? "true" : "false", noise, truth.seconds, err[0], err[1], err[2],
        c.relative_l2, c.max_difference, c.fraction_over, c.lit_pixels, shown.mean_levels, shown.fraction_over);
    std::fflush(stdout);
}

// ", MS ms after it became known" (and how) for --since-known, else empty: part of what
// --vdb, --exr and --blender say the frame is.
std::string since_known_text(const app::ShotArgs& a) {
    if (!a.since_known_ms) return {};
    return ", " + core::format_number(*a.since_known_ms, 6) + " ms after it became known" +
           (a.since_leader ? " at its leader's start" : "") + (a.without_instant ? ", without the instant way" : "");
}

// --vdb: the density and the frame's lightning S at t in every baked direction (zeros when no
// flash glows at t; none without lightning), on the lighting grid.
void write_frame_vdb(view::StormView& view, double t, const view::ViewOptions& opt, const app::ShotArgs& a,
                     const transport::SourceField* shown_field) {
    app::LightingVdb v;
    const scene::Scene& s = view.scene();
    v.scene = s.name + " (" + a.scene.string() + ")";
    v.extinction = s.medium.extinction;
    v.density = &view.density();
    if (view.has_lightning()) {
        const std::vector<glm::dvec3>& dirs = view.bases().directions();
        v.source.assign(dirs.size(), core::Grid3<float>(view.bases().lighting()));
        v.directions = dirs;
        bool lit = true;
        if (shown_field) {  // --since-known: the frame as it was shown then
            for (std::size_t m = 0; m < dirs.size(); ++m) {
                const std::span<const float> d = shown_field->direction(m);
                v.source[m].data.assign(d.begin(), d.end());
            }
        } else {
            runtime::ReconstructOptions ro;
            ro.components = opt.components;
            ro.wait_for_strikes = true;
            const runtime::Frame& f = view.pipeline().build(t, {}, ro);
            lit = f.lit;
            if (f.lit)
                for (std::size_t i = 0; i < f.radiance.directions.size(); ++i)
                    v.source.at(std::size_t(f.radiance.directions[i])).data = f.radiance.values[i];
        }
        v.source_meaning = "the lightning's S of the frame at t = " + core::format_number(t, 9) + " s, seed " +
                           std::to_string(a.seed) + ", quality " +
                           std::string(scene::to_string(view.pipeline().quality().preset)) + since_known_text(a) +
                           (lit ? "" : " (no flash glows at t: zero)");
    }
    app::write_lighting_vdb(*a.vdb, v);
}

// What the frame is, for the headers of --exr and --blender.
std::string frame_label(view::StormView& view, double t, const app::ShotArgs& a) {
    std::string f = "t = " + core::format_number(t, 9) + " s";
    if (view.has_lightning())
        f += ", strike seed " + std::to_string(a.seed) + ", quality " +
             std::string(scene::to_string(view.pipeline().quality().preset));
    return f + since_known_text(a);
}

// --exr: the frame's linear radiance (and with --exr-passes its terms and transmittance), the
// camera as vectors and as OpenEXR's standard worldToCamera / worldToNDC, the units.
void write_frame_exr(view::StormView& view, const render::Camera& cam, double t, const view::ViewOptions& opt,
                     const app::ShotArgs& a, GivenLight shown, double shown_exposure, const std::filesystem::path& out,
                     const std::string& lit_by) {
    const view::LinearFrame f =
        view::render_linear(view, cam, t, a.width, a.height, opt, shown.source, a.exr_passes, shown.rain);
    std::vector<app::ExrLayer> layers{{"", {"R", "G", "B"}, f.radiance}};
    for (const view::LinearPass& p : f.passes) layers.push_back({p.name, {"R", "G", "B"}, p.rgb});
    if (!f.transmittance.empty()) layers.push_back({"T", {"Y"}, f.transmittance});
    app::ExrHeader h;
    const scene::Scene& s = view.scene();
    h.text = {{"fulgurUnits",
               "R, G, B: radiance in W m^-2 sr^-1 (linear, before exposure and tone map, without the "
               "eye's glare); T.Y: the cloud's transmittance along the pixel's ray"},
              {"fulgurScene", s.name + " (" + a.scene.string() + ")"},
              {"fulgurFrame", frame_label(view, t, a) + lit_by},
              {"fulgurLengthUnit", "m (world space; z up)"}};
    if (a.exr_passes)
        h.text.push_back(
            {"fulgurPasses", "lightning + static + glow + channel + background = R, G, B (docs/render.md)"});
    h.vectors = {{"cameraPosition", cam.position}, {"cameraTarget", cam.target}, {"cameraUp", cam.up}};
    h.numbers = {{"cameraVerticalFovDeg", cam.vertical_fov_deg},
                 {"fulgurDisplayExposure", shown_exposure},
                 {"fulgurInternalScale", a.internal_scale}};
    const glm::dmat4 world_to_camera = glm::lookAt(cam.position, cam.target, cam.up);
    h.world_to_camera = world_to_camera;
    h.world_to_ndc =
        glm::perspective(glm::radians(cam.vertical_fov_deg), double(a.width) / double(a.height), 0.5, 1e6) *
        world_to_camera;
    app::write_exr(out, a.width, a.height, layers, h);
}

// --blender: the frame's lit channel (as shown: the frame at t), its camera and its lights.
void write_frame_blender(view::StormView& view, const render::Camera& cam, double t, const view::ViewOptions& opt,
                         const app::ShotArgs& a, const core::Grid3<float>* undetailed) {
    std::vector<lightning::LitSegment> drawn;
    // Cycles renders every order of scattering: the flash is exported whole or not at all.
    if (opt.components.single != opt.components.multiple)
        throw core::Error("--blender",
                          "Cycles renders all orders of scattering: turn both single and multiple off "
                          "(no flash light in the cloud) or neither");
    if (view.has_lightning()) view.pipeline().storm().lit(t, drawn);
    std::span<const lightning::LitSegment> lit;  // the cloud's lights: none with its flash light off
    if (opt.components.single) lit = drawn;
    app::BlenderExport e;
    e.drawn_channel = drawn;
    e.channel_radius = opt.bolt_radius;
    e.scene = view.scene().name + " (" + a.scene.string() + ")";
    e.frame = frame_label(view, t, a);
    e.camera = cam;
    e.width = a.width;
    e.height = a.height;
    // A quarter of a density voxel: the points differ from the line only within a voxel of it.
    e.light_spacing = 0.25 * view.density().geom.voxel_size;
    e.undetailed = undetailed;
    app::write_blender_export(*a.blender, view, opt, lit, e);
}

}  // namespace

int main(int argc, char** argv) {
    app::ShotArgs a;
    if (const std::optional<int> status = app::start(argc, argv, a, app::parse_shot_args, app::shot_usage))
        return *status;
    try {
        scene::Scene s = scene::load_scene(a.scene);
        // --camera replaces the scene's before anything is planned: a static light solved
        // toward the camera (transport.static_light.directions "camera") is solved toward it.
        if (a.camera) s.camera = a.camera;
        if (a.static_toward_camera) {
            s.transport.static_monte_carlo = true;
            s.transport.static_toward_camera = true;
            s.transport.static_keep_transport_grid = true;
        }
        // --strike-grid: the quality's grid set before the density is made, so its cost is
        // checked with the rest (scene::check_cost) before anything is solved.
        if (a.strike_grid > 0 || a.strike_toward_camera) s.quality = shot_options_quality(s, shot_quality(s, a), a);
        // The images never overwrite the scene, its cloud or its baked file, nor each other.
        std::vector<core::NamedPath> inputs{{"scene", a.scene},
                                            {"baked file", a.fgb ? *a.fgb : bake::default_fgb_path(s)}};
        if (s.cloud.kind != scene::CloudSource::Kind::Generator) inputs.push_back({"cloud file", s.cloud.file});
        std::vector<core::NamedPath> outputs{{"image (-o)", a.output}};
        if (a.vdb) outputs.push_back({"VDB (--vdb)", *a.vdb});
        if (a.exr) outputs.push_back({"EXR (--exr)", *a.exr});
        if (a.blender) {
            outputs.push_back({"Blender frame (--blender)", *a.blender / "frame.json"});
            outputs.push_back({"Blender density (--blender)", *a.blender / "density.vdb"});
        }
        if (a.reference) {
            outputs.push_back({"reference image", *a.reference});
            outputs.push_back({"difference image", app::reference_diff_path(*a.reference)});
            outputs.push_back({"comparison image", app::reference_compare_path(*a.reference)});
        }
        core::check_distinct_files(inputs, outputs);
        app::SceneDensity loaded = app::load_density(s);
        const sky::ScenePlan plan = app::plan_and_print(s, loaded.density, stderr);
        const auto fgb = app::bases_for(plan, s, loaded.density, a.fgb);
        auto ctx = platform::create_headless({.width = a.width, .height = a.height});
        const view::StaticSetup setup = app::static_setup(plan, stderr, &loaded);
        view::StormView view(std::move(s), std::move(loaded.density), fgb, ctx->get_proc_address(), setup);
        double t = a.time;
        if (view.has_lightning()) {
            lightning::LightningParams lp = view.scene().lightning;
            lp.schedule.strike_rate = 0.0;  // only the requested strike (after the bake check: same .fgb as the demo)
            view.set_lightning(lp);
            scene::Quality q = shot_quality(view.scene(), a);
            q = shot_options_quality(view.scene(), q, a);
            if (a.since_known_ms) q.lookahead = 0.0;  // nobody scheduled it
            using P = scene::Quality::Preset;
            if (a.without_instant && (q.preset == P::Paper || q.preset == P::Instant))
                throw core::Error("--without-instant", "the " + std::string(scene::to_string(q.preset)) +
                                                           " preset solves no strike ahead; use hybrid, per_strike, "
                                                           "per_strike_mc or reference");
            if (a.quality || a.since_known_ms) view.set_quality(q);
            // --since-known: known when it strikes, so lit the instant way until the preset's own
            // solve is ready ("Strike now"); --without-instant: counted as scheduled with
            // lookahead 0 (the bases until then).
            const bool known_ahead = !a.since_known_ms || a.without_instant;
            const std::size_t strike = view.pipeline().strike_at(0.0, a.seed, known_ahead);
            const lightning::Strike& k = view.pipeline().storm().strike(strike);
            if (a.time_after_return_stroke) t += k.profile.stroke_onset.at(0);
            if (a.since_leader) {  // known since the strike started
                if (!(t >= k.time))
                    throw core::Error("--since-known leader", "the frame at --time is before the strike starts (" +
                                                                  core::format_number(k.time, 6) + " s)");
                a.since_known_ms = (t - k.time) * 1000.0;
            }
        } else if (a.time_after_return_stroke || (a.reference && a.against != "static") || a.since_known_ms) {
            throw core::Error(a.scene.string(), std::string("the scene has no lightning: ") +
                                                    (a.reference        ? "--reference has no frame to solve"
                                                     : a.since_known_ms ? "--since-known has no strike to wait for"
                                                                        : "--time +T has no return stroke to follow"));
        }
        view::ViewOptions opt;
        opt.wait_for_strikes = true;  // offline: the preset's own light, never its fallback
        opt.settings.exposure_compensation = a.exposure_ev;
        opt.settings.internal_scale = a.internal_scale;
        if (a.manual_exposure) {
            opt.settings.auto_exposure = false;
            opt.settings.exposure = *a.manual_exposure;
        }
        for (const std::string& off : a.off) {
            opt.sun &= off != "sun";
            opt.sky &= off != "sky";
            opt.sun_full_resolution &= off != "silver-lining";
            opt.settings.glow &= off != "glow";
            opt.settings.glare &= off != "glare";
            opt.settings.bolt &= off != "bolt";
            opt.settings.ground &= off != "ground";
            opt.settings.ground_scatter &= off != "ground-scatter";
            opt.components.single &= off != "single";
            opt.components.multiple &= off != "multiple";
            opt.settings.detail &= off != "detail";
            opt.settings.rain &= off != "rain";
            opt.settings.dither &= off != "dither";
            opt.settings.display_upsample &= off != "display-upsample";
            opt.settings.ground_rain_map &= off != "ground-rain-map";
        }
        // The view: --camera, else the scene's, else the default; printed with every part explicit.
        const std::optional<scene::CameraSpec> chosen = view.scene().camera;
        const render::Camera cam = view::scene_camera(chosen, view.density());
        const scene::CameraSpec stated = chosen && chosen->kind == scene::CameraSpec::Kind::LookAt
                                             ? *chosen
                                             : view::explicit_orbit(chosen, view.density());
        std::optional<transport::SourceField> shown;  // --since-known: the frame as it was then
        transport::SourceField shown_rain;            // and its light at the rain (empty: none)
        if (a.since_known_ms) {
            opt.wait_for_strikes = false;
            shown = since_known_field(view, t, opt, a, shown_rain);
        }
        const transport::SourceField* shown_field = shown ? &*shown : nullptr;
        const GivenLight shown_light{shown_field, &shown_rain};
        // Medians over --repeat frames: the first one also compiles shaders and uploads the
        // density; the run time rebuilds the same frame each time (same strike, same t). The
        // frame index (which varies the ray-march jitter) stays the same too, so the image
        // written is the one a single render writes: --repeat only times it.
        std::vector<view::FrameReport> reps;
        for (int k = 0; k < a.repeat; ++k)
            reps.push_back(view.render(cam, t, a.width, a.height, opt, shown_light.source, shown_light.rain));
        view::FrameReport r = reps.back();
        if (reps.size() > 1) r = view::median_report(reps);
        ctx->present();
        const auto px = ctx->read_rgba8();
        core::write_png(a.output, a.width, a.height, 4, px);
        std::string line = app::timings_json(r, a.width, a.height);
        line.pop_back();  // the object's closing brace: the camera joins it
        std::cout << line << ",\"camera\":" << scene::camera_json(stated) << "}" << std::endl;
        if (a.vdb) write_frame_vdb(view, t, opt, a, shown_field);
        if (a.blender) write_frame_blender(view, cam, t, opt, a, loaded.undetailed ? &*loaded.undetailed : nullptr);
        if (a.exr) write_frame_exr(view, cam, t, opt, a, shown_light, r.gpu.exposure, *a.exr, "");
        if (a.reference && a.against == "static")
            render_static_reference(view, ctx.get(), cam, t, opt, a, px, shown_light);
        else if (a.reference)
            render_reference(view, ctx.get(), cam, t, opt, a, px, shown_light);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur-shot: %s\n", e.what());
        return app::kExitFailure;
    }
    return 0;
}
