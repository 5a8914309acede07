#include "view/view.h"

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <span>

namespace fulgur::view {

namespace {

// The share of the rain's extinction the flash's solves carry, which the ground's flash lights
// cross (render::VolumeDesc::rain_solved_share). The presets that trace their strikes' paths
// carry the rain at its own extinction (transport::PathMix), and their paths tally the light
// the drops scatter onto the ground; the lattice (per_strike) carries it as cloud of equal
// transport coefficient (sky::rain_media_density), whose share the others take too: paper and
// hybrid light the ground by the channel alone, and the lesser attenuation stands in there for
// the light the drops scatter forward.
double flash_rain_share(const scene::Scene& s, const scene::Quality& q) {
    if (!s.rain) return 1.0;
    using P = scene::Quality::Preset;
    if (q.preset == P::PerStrikeMc || q.preset == P::Instant || q.preset == P::Reference) return 1.0;
    return sky::rain_media_density(s.medium, *s.rain) * s.medium.extinction;
}

// The share for a frame the pipeline built: the preset's, except that a frame lit only by
// strikes lit the instant way (unscheduled strikes under hybrid or per_strike) was lit by paths
// through the drops at their own extinction, which tallied the drops' forward light onto the
// ground themselves.
double frame_rain_share(const scene::Scene& s, const runtime::Frame& f) {
    const bool traced = f.strikes_instant > 0 && f.strikes_instant == f.strikes_solved && f.strikes_fallback == 0;
    return traced && s.rain ? 1.0 : flash_rain_share(s, s.quality);
}

}  // namespace

std::filesystem::path ensure_baked(
    const scene::Scene& s, const core::Grid3<float>& density, const std::optional<std::filesystem::path>& explicit_fgb,
    const bake::Progress& progress,
    const std::function<void(const std::filesystem::path& fgb, const std::string& why)>& on_bake) {
    if (explicit_fgb) {
        if (!std::filesystem::exists(*explicit_fgb)) throw core::Error(explicit_fgb->string(), "no such .fgb file");
        return *explicit_fgb;
    }
    const std::filesystem::path fgb = bake::default_fgb_path(s);
    std::function<void(const std::string&)> tell;
    if (on_bake) tell = [&](const std::string& why) { on_bake(fgb, why); };
    bake::bake_if_stale(s, density, fgb, progress, tell);
    return fgb;
}

std::optional<std::filesystem::path> bases_for(
    const sky::ScenePlan& plan, const scene::Scene& s, const core::Grid3<float>& density,
    const std::optional<std::filesystem::path>& explicit_fgb, const bake::Progress& progress,
    const std::function<void(const std::filesystem::path& fgb, const std::string& why)>& on_bake) {
    if (plan.lightning) return ensure_baked(s, density, explicit_fgb, progress, on_bake);
    if (explicit_fgb)
        throw core::Error(explicit_fgb->string(),
                          "the scene has no lightning: it renders without a .fgb (plan: no "
                          "virtual-light bake)");
    return std::nullopt;
}

render::Camera default_camera(const core::Grid3<float>& density, double azimuth_deg, double elevation_deg,
                              double distance_factor) {
    glm::dvec3 target;
    double distance = 0.0;
    scene::default_orbit(density.geom, distance_factor, target, distance);
    return render::Camera::orbit(target, distance, azimuth_deg, elevation_deg);
}

render::Camera scene_camera(const std::optional<scene::CameraSpec>& spec, const core::Grid3<float>& density) {
    if (!spec) return default_camera(density);
    if (spec->kind == scene::CameraSpec::Kind::LookAt)
        return render::Camera{spec->position, spec->target, spec->up, spec->vertical_fov_deg};
    const scene::CameraSpec o = explicit_orbit(spec, density);
    return render::Camera::orbit(*o.orbit_target, *o.distance, o.azimuth_deg, o.elevation_deg, o.vertical_fov_deg);
}

scene::CameraSpec explicit_orbit(const std::optional<scene::CameraSpec>& spec, const core::Grid3<float>& density) {
    scene::CameraSpec o = spec.value_or(scene::CameraSpec{});
    if (o.kind == scene::CameraSpec::Kind::LookAt) {
        const glm::dvec3 v = o.position - o.target;  // from the target toward the camera
        const double r = glm::length(v);
        o.kind = scene::CameraSpec::Kind::Orbit;
        o.orbit_target = o.target;
        o.distance = r;
        o.elevation_deg = glm::degrees(std::asin(std::clamp(v.z / r, -1.0, 1.0)));
        o.azimuth_deg = glm::degrees(std::atan2(v.y, v.x));
        o.up = {0.0, 0.0, 1.0};
        o.position = o.target = glm::dvec3(0.0);
        return o;
    }
    glm::dvec3 target;
    double distance = 0.0;
    scene::default_orbit(density.geom, 1.1, target, distance);
    if (!o.orbit_target) o.orbit_target = target;
    if (!o.distance) o.distance = distance;
    return o;
}

StormView::StormView(scene::Scene s, core::Grid3<float> density, const std::optional<std::filesystem::path>& fgb,
                     render::GetProcAddress gl, const StaticSetup& setup)
    : scene_(std::move(s)), density_(std::move(density)) {
    bake::PlanOptions po;
    po.estimate = false;
    plan_ = setup.plan ? *setup.plan : sky::plan_scene(scene_, density_, po);
    if (plan_.lightning) {
        if (!fgb)
            throw core::Error(scene_.path.string(), "the scene has lightning: its .fgb is needed (view::bases_for)");
        bases_.emplace(runtime::BakedBases::load(*fgb, bake::expected_metadata(scene_, density_)));
        pipeline_ = std::make_unique<runtime::FramePipeline>(scene_, density_, *bases_);
    } else if (fgb) {
        throw core::Error(fgb->string(), "the scene has no lightning: it renders without a .fgb");
    }
    if (scene_.rain) rain_ = cloud::make_rain(density_, *scene_.rain);
    const cloud::RainField* rain = rain_ ? &*rain_ : nullptr;
    if (plan_.sun || plan_.sky)
        static_ = sky::load_or_solve(scene_, density_, static_media(), plan_, setup.cache, setup.say);
    if (plan_.sun) {
        sun_ = scene_.sun;
        sun_transmittance_ = sky::sun_transmittance(scene_, density_, static_.sun_direction, rain);
    }
    renderer_ = std::make_unique<render::Renderer>(
        gl, setup.shader_dir.empty() ? render::default_shader_dir() : setup.shader_dir);
    // With detail the renderer erodes the density before its detail at every sample.
    std::optional<core::Grid3<float>> made;
    const core::Grid3<float>* drawn = &density_;
    if (scene_.cloud.detail) {
        drawn =
            setup.undetailed_density ? setup.undetailed_density : &made.emplace(scene::make_undetailed_density(scene_));
        if (!(drawn->geom == density_.geom))
            throw core::Error("StaticSetup::undetailed_density", "is not on the scene's density grid");
    }
    renderer_->set_volume({.density = drawn,
                           .extinction = scene_.medium.extinction,
                           .detail = scene_.cloud.detail,
                           .rain = rain,
                           .rain_solved_share = flash_rain_share(scene_, scene_.quality)});
}

void StormView::set_lightning(const lightning::LightningParams& p) {
    lightning::validate(p);
    if (!pipeline_) throw core::Error(scene_.path.string(), "the scene has no lightning");
    scene_.lightning = p;
    last_ = nullptr;
    pipeline_.reset();
    pipeline_ = std::make_unique<runtime::FramePipeline>(scene_, density_, *bases_);
}

void StormView::set_sun(const scene::Sun& sun) {
    if (!plan_.sun) throw core::Error(scene_.path.string(), "the scene's plan solves no sun");
    sun_ = sun;
    ++static_version_;
}

void StormView::set_sun_solve(sky::SunSolve&& solve) {
    if (!plan_.sun) throw core::Error(scene_.path.string(), "the scene's plan solves no sun");
    static_.sun = std::move(solve.field);
    static_.sun_direction = solve.direction;
    sun_transmittance_ = std::move(solve.transmittance);
    ++static_version_;
}

void StormView::set_static_light(sky::StaticLight light) {
    const auto field_like = [](const sky::LightField& f, const sky::LightField& like) {
        return f.single.data.size() == like.single.data.size() && f.multiple.data.size() == like.multiple.data.size();
    };
    const auto sky_like = [&](const sky::SkyField& f, const sky::SkyField& like) {
        return field_like(f.zenith, like.zenith) && field_like(f.horizon, like.horizon) &&
               field_like(f.uniform, like.uniform);
    };
    if (light.sun.has_value() != static_.sun.has_value() || light.sky.has_value() != static_.sky.has_value() ||
        (light.sun && !field_like(*light.sun, *static_.sun)) || (light.sky && !sky_like(*light.sky, *static_.sky)))
        throw core::Error(scene_.path.string(), "set_static_light: a static light of another shape than the plan's");
    if (light.sun && light.sun_direction != static_.sun_direction)
        throw core::Error(scene_.path.string(), "set_static_light: a sun solved for another direction");
    static_ = std::move(light);
    ++static_version_;
}

StormView::StaticTruthSolve StormView::solve_static_truth(const sky::TruthOptions& options) {
    if (!plan_.sun && !plan_.sky) throw core::Error(scene_.path.string(), "the scene has no sun and no sky");
    core::Stopwatch sw;
    std::vector<glm::dvec3> dirs;
    if (static_.sun)
        dirs = static_.sun->multiple.directions.empty() ? static_.sun->single.directions
                                                        : static_.sun->multiple.directions;
    else
        dirs = transport::output_directions(scene_.effective_directions());
    StaticTruthSolve out;
    out.light = sky::truth_of(scene_, density_, plan_, static_media(), static_, dirs, options, &out.noise);
    out.seconds = sw.seconds();
    return out;
}

sky::ColourField StormView::static_colour(const sky::ComposeOptions& options, const sky::StaticLight* light) const {
    return sky::compose(light ? *light : static_, sun_, scene_.sky, options);
}

void StormView::update_static_light(const ViewOptions& o) {
    const bool sun = plan_.sun && o.sun && static_.sun.has_value() && sun_.has_value();
    const bool sky = plan_.sky && o.sky && static_.sky.has_value();
    // The sun's order 1 at full resolution in the march, or on the lighting grid with the rest.
    const bool full = o.sun_full_resolution;
    const Uploaded want{true, sun, sky, !full, o.components.single, o.components.multiple, static_version_};
    const auto same = [](const Uploaded& a, const Uploaded& b) {
        return a.valid == b.valid && a.sun == b.sun && a.sky == b.sky && a.sun_single == b.sun_single &&
               a.single == b.single && a.multiple == b.multiple && a.version == b.version;
    };
    if (same(uploaded_, want)) return;
    sky::ComposeOptions co;
    co.sun = sun;
    co.sky = sky;
    co.sun_single = !full;
    co.single = o.components.single;
    co.multiple = o.components.multiple;
    const sky::ColourField c = sky::compose(static_, sun_, scene_.sky, co);
    if (c.empty()) {
        renderer_->clear_static();
    } else {
        render::StaticUpload up;
        up.geometry = c.geom;
        up.direction_count = int(c.directions.size());
        up.albedo = scene_.medium.albedo;
        for (const std::vector<float>& v : c.rgb) up.rgb.emplace_back(v.data(), v.size());
        // The ground's static light: what the cloud scatters down and the sky it leaves.
        if (ground_version_ != static_version_) {
            const solve::Media& m = static_media();
            const auto cells = sky::static_ground_cells(scene_, m.lighting.density.geom);
            ground_ = cells ? sky::static_ground(m, static_, *cells) : sky::StaticGround{};
            ground_version_ = static_version_;
        }
        const std::vector<float> ground_rgb = sky::compose_ground(ground_, sun_, scene_.sky, sun, sky);
        if (!ground_rgb.empty()) {
            up.ground.origin = ground_.cells.origin;
            up.ground.cell = ground_.cells.cell;
            up.ground.nx = ground_.cells.nx;
            up.ground.ny = ground_.cells.ny;
            up.ground.rgb = ground_rgb;
        }
        renderer_->upload_static(up);
    }
    if (sun) {
        render::SunDesc d;
        d.direction = static_.sun_direction;
        d.irradiance_rgb = sun_->irradiance * sun_->colour;
        d.albedo = scene_.medium.albedo;
        d.g = scene_.medium.g;
        d.transmittance = &sun_transmittance_;
        d.scatter = full && o.components.single && scene_.effects.single_scattering;
        renderer_->set_sun(d);
    } else {
        renderer_->clear_sun();
    }
    uploaded_ = want;
}

void StormView::set_quality(const scene::Quality& q) {
    scene_.quality = q;
    if (pipeline_) pipeline_->set_quality(q);
    if (renderer_) renderer_->set_rain_solved_share(flash_rain_share(scene_, q));
}

const solve::Media& StormView::media() {
    if (!media_) media_ = solve::make_media(scene_, density_);
    return *media_;
}

const solve::Media& StormView::static_media() {
    if (!static_media_) static_media_ = sky::static_media(scene_, density_, rain_ ? &*rain_ : nullptr);
    return *static_media_;
}

double StormView::time_all_directions(double t, const runtime::Components& components, bool wait_for_strikes) {
    if (!pipeline_) throw core::Error(scene_.path.string(), "the scene has no lightning: no frame to solve");
    runtime::ReconstructOptions ro;
    ro.components = components;
    ro.wait_for_strikes = wait_for_strikes;
    std::vector<double> ms;
    for (int k = 0; k < 5; ++k) {
        last_ = &pipeline_->build(t, {}, ro);
        ms.push_back(last_->times.total());
    }
    std::nth_element(ms.begin(), ms.begin() + 2, ms.end());
    return ms[2];
}

StormView::TruthSolve StormView::solve_truth(double t, const runtime::Components& components,
                                             const runtime::TruthOptions& options, bool wait_for_strikes) {
    TruthSolve out;
    out.basis_ms = time_all_directions(t, components, wait_for_strikes);
    core::Stopwatch sw;
    runtime::TruthOptions o = options;  // like with like: a strike solved toward the camera, its truth too
    if (pipeline_) o.toward = scene::strike_toward(scene_, pipeline_->quality(), density_.geom);
    const runtime::Truth truth = runtime::truth(scene_, density_, last_->segments, {}, o);
    out.seconds = sw.seconds();
    out.field = truth.sum(components);
    out.rain = truth.rain_light(scene_, components);
    out.noise = truth.noise;
    return out;
}

StormView::DirectSolve StormView::solve_direct(double t, const runtime::Components& components, bool wait_for_strikes) {
    DirectSolve out;
    out.basis_ms = time_all_directions(t, components, wait_for_strikes);
    const solve::Media& m = media();
    core::Stopwatch sw;
    out.field = runtime::direct_solve(scene_, m, last_->sources, components);
    out.seconds = sw.seconds();
    return out;
}

void StormView::check_field(const transport::SourceField& f, const char* where) const {
    if (!bases_) throw core::Error(where, "the scene has no lightning: no bases");
    if (!(f.geom == bases_->lighting()) || f.directions.size() != bases_->directions().size() ||
        f.data.size() != f.cells() * f.directions.size())
        throw core::Error(where, "the field is not on the bases' lighting grid with all " +
                                     std::to_string(bases_->directions().size()) + " directions");
}

double StormView::reconstruction_error(const transport::SourceField& reference) {
    check_field(reference, "StormView::reconstruction_error");
    if (!last_ || !last_->lit) return 0.0;
    const runtime::RadianceField& r = last_->radiance;
    const std::vector<float>& density = media().lighting.density.data;
    core::RelativeL2 e;  // ~10^5 terms spanning many orders of magnitude: compensated sums
    for (std::size_t k = 0; k < r.directions.size(); ++k) {
        const std::span<const float> ref = reference.direction(std::size_t(r.directions[k]));
        for (std::size_t i = 0; i < ref.size(); ++i)
            if (density[i] > 0.0f) e.add(double(r.values[k][i]), double(ref[i]));
    }
    return e.value();
}

namespace {

// A field on the lighting grid with every direction, as the renderer takes it: the directions
// `dirs` of `ndir`.
render::SourceUpload upload_of(const transport::SourceField& f, int ndir, const std::vector<int>& dirs) {
    render::SourceUpload up;
    up.geometry = f.geom;
    up.direction_count = ndir;
    up.directions = dirs;
    for (int m : dirs) up.values.push_back(f.direction(std::size_t(m)));
    return up;
}

// A frame's field (the directions it holds), as the renderer takes it.
render::SourceUpload upload_of(const runtime::RadianceField& r) {
    render::SourceUpload up;
    up.geometry = r.geometry;
    up.direction_count = r.direction_count;
    up.directions = r.directions;
    for (const auto& v : r.values) up.values.emplace_back(v.data(), v.size());
    return up;
}

// What the renderer draws of the lit stretches: each with its intensity and the drawn radius.
render::LitChannel lit_channel(std::span<const lightning::LitSegment> lit, double radius) {
    render::LitChannel bolt;
    bolt.segments.reserve(lit.size());
    for (const lightning::LitSegment& s : lit)
        bolt.segments.push_back({glm::vec3(s.a), glm::vec3(s.b), float(s.intensity), float(radius)});
    return bolt;
}

}  // namespace

double StormView::warm_up(const render::Camera& camera, int width, int height, const ViewOptions& options) {
    const auto t0 = std::chrono::steady_clock::now();
    render::Settings st = frame_settings(options);
    // The programs are the full size's: a moving camera's fill and block as Auto picks them
    // there (the internal height decides), everything else independent of the size.
    const int full_march_height = std::max(1, int(std::lround(height * st.internal_scale)));
    st.temporal_light = render::temporal_upsamples(st.temporal_light, camera.vertical_fov_deg, full_march_height)
                            ? render::TemporalLight::Upsample
                            : render::TemporalLight::Reproject;
    st.temporal_moving_block =
        render::temporal_block(st.temporal_moving_block, camera.vertical_fov_deg, full_march_height);
    const int w = std::max(64, width / 4), h = std::max(36, height / 4);
    // The camera turned about the vertical through its target (degrees).
    const auto turned = [&](double deg) {
        render::Camera c = camera;
        const glm::dvec3 off = c.position - c.target;
        const double a = glm::radians(deg), ca = std::cos(a), sa = std::sin(a);
        c.position = c.target + glm::dvec3(ca * off.x - sa * off.y, sa * off.x + ca * off.y, off.z);
        return c;
    };
    update_static_light(options);
    renderer_->set_channel({});
    renderer_->clear_source();
    int frame = 0;
    const auto draw = [&](const render::Camera& c) {
        st.frame_index = std::uint32_t(frame++);
        renderer_->render(c, st, w, h);
    };
    // Between flashes: still (marched, then reused), then orbiting.
    draw(camera);
    draw(camera);
    draw(turned(1.0));
    draw(turned(2.0));
    if (pipeline_ && bases_) {
        // A flash: a vertical channel from the middle of the cloud to the ground, S uniform on
        // the lighting grid in every direction.
        const core::GridGeometry& lg = bases_->lighting();
        const glm::dvec3 mid = lg.origin + 0.5 * lg.extent();
        const double ground = scene_.lightning.bolt.ground_height;
        const std::vector<float> ones(lg.cell_count(), 1e-3f);
        render::SourceUpload up;
        up.geometry = lg;
        up.direction_count = int(bases_->directions().size());
        for (int m = 0; m < up.direction_count; ++m) {
            up.directions.push_back(m);
            up.values.emplace_back(ones);
        }
        const auto show = [&](double g, double reach, bool ground_light) {
            render::LitChannel ch;
            const glm::dvec3 top = mid, foot(mid.x, mid.y, ground);
            ch.segments.push_back({glm::vec3(top), glm::vec3(top + (foot - top) * reach), float(1e3 * g), 1.0f});
            if (ground_light) ch.ground = {glm::dvec2(lg.origin), lg.voxel_size, 2, 2, std::vector<float>(4, 0.0f)};
            renderer_->set_channel(ch);
            renderer_->upload_source(up);
        };
        for (const bool ground_light : {true, false}) {
            const double at = ground_light ? 2.0 : 4.0;
            // A leader reaching down (new shapes, still), the stroke dimming (settling, then reused,
            // the glare summed from the history), the camera orbiting through it, a new shape then.
            show(0.1, 0.5, ground_light);
            draw(turned(at));
            for (const double g : {1.0, 0.7, 0.5, 0.35, 0.25, 0.2}) {
                show(g, 1.0, ground_light);
                draw(turned(at));
            }
            show(0.15, 1.0, ground_light);
            draw(turned(at + 1.0));
            show(0.1, 0.7, ground_light);
            draw(turned(at + 2.0));
            // A cut during a flash: every pixel marched with the flash's light (as the first
            // frame a history makes when it opens on a flash).
            draw(turned(at + 45.0));
        }
        renderer_->set_channel({});
        renderer_->clear_source();
    }
    renderer_->reset_history();
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

FrameReport StormView::render(const render::Camera& camera, double t, int width, int height, const ViewOptions& options,
                              const transport::SourceField* source, const transport::SourceField* rain_source) {
    using clock = std::chrono::steady_clock;
    const auto t0 = clock::now();
    FrameReport rep;
    upload_frame(camera, t, options, source, rain_source, rep);
    rep.gpu = renderer_->render(camera, frame_settings(options), width, height);
    rep.wall_ms = std::chrono::duration<double, std::milli>(clock::now() - t0).count();
    return rep;
}

void StormView::upload_frame(const render::Camera& camera, double t, const ViewOptions& options,
                             const transport::SourceField* source, const transport::SourceField* rain_source,
                             FrameReport& rep) {
    if (pipeline_) {
        render_lightning(camera, t, options, source, rain_source, rep);
    } else {
        if (source) throw core::Error("StormView::render", "the scene has no lightning: no field to show");
        renderer_->set_channel({});
        renderer_->clear_source();
    }
    update_static_light(options);
}

FrameReport StormView::render_into_host(const render::HostFrame& host, double t, int width, int height,
                                        const ViewOptions& options) {
    using clock = std::chrono::steady_clock;
    const auto t0 = clock::now();
    const render::Camera camera =
        render::camera_from_matrices(host.view, host.projection, double(width) / double(height));
    FrameReport rep;
    upload_frame(camera, t, options, nullptr, nullptr, rep);
    rep.gpu = renderer_->render_into_host(host, frame_settings(options), width, height);
    rep.wall_ms = std::chrono::duration<double, std::milli>(clock::now() - t0).count();
    return rep;
}

std::vector<render::Renderer::FlashLight> StormView::flash_lights(double t, int k, const ViewOptions& options) {
    if (!pipeline_) return {};
    std::vector<lightning::LitSegment> lit;
    pipeline_->storm().lit(t, lit);
    renderer_->set_channel(lit_channel(lit, options.bolt_radius));
    return renderer_->flash_lights(k, scene_.lightning.bolt.ground_height);
}

render::Settings StormView::frame_settings(const ViewOptions& options) const {
    render::Settings st = options.settings;
    st.ground_height = scene_.lightning.bolt.ground_height;
    st.flash_colour = scene_.lightning_colour;
    if (scene_.sky) {
        st.sky_zenith = scene_.sky->zenith();
        st.sky_horizon = scene_.sky->horizon();
        st.star_radiance = scene_.sky->star_radiance;
    }
    // What the scene switched off is not drawn whatever the options say.
    st.glow = st.glow && scene_.effects.glow;
    st.glare = st.glare && scene_.effects.glare;
    st.ground = st.ground && scene_.effects.ground;
    return st;
}

void StormView::render_lightning(const render::Camera& camera, double t, const ViewOptions& options,
                                 const transport::SourceField* source, const transport::SourceField* rain_source,
                                 FrameReport& rep) {
    const int ndir = int(bases_->directions().size());
    std::vector<int> dirs;
    for (const render::DirectionUse& u :
         renderer_->needed_directions(camera, bases_->lighting(), ndir, options.settings.direction_min_weight))
        dirs.push_back(u.index);
    runtime::ReconstructOptions ro;
    ro.components = options.components;
    ro.wait_for_strikes = options.wait_for_strikes;
    const runtime::Frame& f = pipeline_->build(t, dirs, ro);
    last_ = &f;
    rep.stages = f.times;
    rep.lit = f.lit;
    // The caller's own S (a reference) is the preset's kind of light; the pipeline's may be a
    // strike lit the instant way.
    renderer_->set_rain_solved_share(source ? flash_rain_share(scene_, scene_.quality) : frame_rain_share(scene_, f));

    render::LitChannel channel = lit_channel(f.segments, options.bolt_radius);
    if (!f.ground.empty()) {
        const transport::GroundTally& c = f.ground.cells;
        channel.ground = {glm::dvec2(c.origin), c.cell, c.nx, c.ny, f.ground.data};
    }
    renderer_->set_channel(channel);
    if (source) {
        check_field(*source, "StormView::render");
        renderer_->upload_source(upload_of(*source, ndir, dirs));
        if (rain_source && !rain_source->data.empty()) {
            check_field(*rain_source, "StormView::render (rain_source)");
            renderer_->upload_rain_source(upload_of(*rain_source, ndir, dirs));
        } else {
            renderer_->clear_rain_source();  // the channel alone lights the rain
        }
    } else if (f.lit && !f.radiance.values.empty()) {
        // S on the transport grid where the quality keeps the strikes there.
        renderer_->upload_source(upload_of(f.fine.values.empty() ? f.radiance : f.fine));
        if (f.rain.values.empty())
            renderer_->clear_rain_source();
        else
            renderer_->upload_rain_source(upload_of(f.rain));
    } else {
        renderer_->clear_source();
    }
}

FrameReport median_report(const std::vector<FrameReport>& reps) {
    FrameReport m = reps.back();
    auto med = [&](auto get) {
        std::vector<double> v;
        for (const FrameReport& r : reps) v.push_back(get(r));
        std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
        return v[v.size() / 2];
    };
    m.stages.bolt = med([](const FrameReport& r) { return r.stages.bolt; });
    m.stages.sources = med([](const FrameReport& r) { return r.stages.sources; });
    m.stages.splat = med([](const FrameReport& r) { return r.stages.splat; });
    m.stages.accumulate = med([](const FrameReport& r) { return r.stages.accumulate; });
    m.stages.inverse_haar = med([](const FrameReport& r) { return r.stages.inverse_haar; });
    m.gpu.wall.upload = med([](const FrameReport& r) { return r.gpu.wall.upload; });
    m.gpu.wall.resolve = med([](const FrameReport& r) { return r.gpu.wall.resolve; });
    m.gpu.wall.glow = med([](const FrameReport& r) { return r.gpu.wall.glow; });
    m.gpu.wall.march = med([](const FrameReport& r) { return r.gpu.wall.march; });
    m.gpu.wall.bolt = med([](const FrameReport& r) { return r.gpu.wall.bolt; });
    m.gpu.wall.glare = med([](const FrameReport& r) { return r.gpu.wall.glare; });
    m.gpu.wall.composite = med([](const FrameReport& r) { return r.gpu.wall.composite; });
    m.gpu.wall.total = med([](const FrameReport& r) { return r.gpu.wall.total; });
    m.wall_ms = med([](const FrameReport& r) { return r.wall_ms; });
    return m;
}

}  // namespace fulgur::view
