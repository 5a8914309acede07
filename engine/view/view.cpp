#include "view/view.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace fulgur::view {

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

render::Camera default_camera(const core::Grid3<float>& density, double azimuth_deg, double elevation_deg,
                              double distance_factor) {
    const core::GridGeometry& g = density.geom;
    const glm::dvec3 ext = g.extent();
    glm::dvec3 target = g.origin + 0.5 * ext;
    target.z = g.origin.z + 0.33 * ext.z;
    const double distance = distance_factor * std::max({ext.x, ext.y, ext.z});
    return render::Camera::orbit(target, distance, azimuth_deg, elevation_deg);
}

StormView::StormView(scene::Scene s, core::Grid3<float> density, const std::filesystem::path& fgb,
                     render::GetProcAddress gl)
    : scene_(std::move(s)),
      density_(std::move(density)),
      bases_(runtime::BakedBases::load(fgb, bake::expected_metadata(scene_, density_))) {
    pipeline_ = std::make_unique<runtime::FramePipeline>(scene_, density_, bases_);
    renderer_ = std::make_unique<render::Renderer>(gl);
    renderer_->set_volume({.density = &density_, .extinction = scene_.medium.extinction});
}

void StormView::set_lightning(const lightning::LightningParams& p) {
    lightning::validate(p);
    scene_.lightning = p;
    last_ = nullptr;
    pipeline_.reset();
    pipeline_ = std::make_unique<runtime::FramePipeline>(scene_, density_, bases_);
}

const bake::Media& StormView::media() {
    if (!media_) media_ = bake::make_media(scene_, density_);
    return *media_;
}

StormView::DirectSolve StormView::solve_direct(double t, const runtime::Components& components) {
    DirectSolve out;
    runtime::ReconstructOptions ro;
    ro.components = components;
    std::vector<double> ms;
    for (int k = 0; k < 5; ++k) {
        last_ = &pipeline_->build(t, {}, ro);
        ms.push_back(last_->times.total());
    }
    std::nth_element(ms.begin(), ms.begin() + 2, ms.end());
    out.basis_ms = ms[2];
    const bake::Media& m = media();
    core::Stopwatch sw;
    out.field = runtime::direct_solve(scene_, m, last_->sources, components);
    out.seconds = sw.seconds();
    return out;
}

void StormView::check_field(const transport::SourceField& f, const char* where) const {
    if (!(f.geom == bases_.lighting()) || f.directions.size() != bases_.directions().size() ||
        f.data.size() != f.cells() * f.directions.size())
        throw core::Error(where, "the field is not on the bases' lighting grid with all " +
                                     std::to_string(bases_.directions().size()) + " directions");
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

FrameReport StormView::render(const render::Camera& camera, double t, int width, int height, const ViewOptions& options,
                              const transport::SourceField* source) {
    using clock = std::chrono::steady_clock;
    const auto t0 = clock::now();
    FrameReport rep;
    const int ndir = int(bases_.directions().size());
    std::vector<int> dirs;
    for (const render::DirectionUse& u :
         renderer_->needed_directions(camera, bases_.lighting(), ndir, options.settings.direction_min_weight))
        dirs.push_back(u.index);
    runtime::ReconstructOptions ro;
    ro.components = options.components;
    const runtime::Frame& f = pipeline_->build(t, dirs, ro);
    last_ = &f;
    rep.stages = f.times;
    rep.lit = f.lit;

    render::Bolt bolt;
    bolt.segments.reserve(f.segments.size());
    for (const lightning::LitSegment& s : f.segments)
        bolt.segments.push_back({glm::vec3(s.a), glm::vec3(s.b), float(s.intensity), float(options.bolt_radius)});
    renderer_->set_bolt(bolt);
    if (source) {
        check_field(*source, "StormView::render");
        render::SourceUpload up;
        up.geometry = source->geom;
        up.direction_count = ndir;
        up.directions = dirs;
        for (int m : dirs) up.values.push_back(source->direction(std::size_t(m)));
        renderer_->upload_source(up);
    } else if (f.lit && !f.radiance.values.empty()) {
        render::SourceUpload up;
        up.geometry = f.radiance.geometry;
        up.direction_count = f.radiance.direction_count;
        up.directions = f.radiance.directions;
        for (const auto& v : f.radiance.values) up.values.emplace_back(v.data(), v.size());
        renderer_->upload_source(up);
    } else {
        renderer_->clear_source();
    }
    render::Settings st = options.settings;
    st.ground_height = scene_.lightning.bolt.ground_height;
    rep.gpu = renderer_->render(camera, st, width, height);
    rep.wall_ms = std::chrono::duration<double, std::milli>(clock::now() - t0).count();
    return rep;
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
    m.gpu.wall.composite = med([](const FrameReport& r) { return r.gpu.wall.composite; });
    m.gpu.wall.total = med([](const FrameReport& r) { return r.gpu.wall.total; });
    m.wall_ms = med([](const FrameReport& r) { return r.wall_ms; });
    return m;
}

}  // namespace fulgur::view
