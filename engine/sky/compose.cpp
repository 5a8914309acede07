// The static light in colour for the renderer, and solving the sun again when it moves
// (sky.h).
#include "sky/sky.h"

#include <atomic>
#include <exception>
#include <mutex>

namespace fulgur::sky {

namespace {

// Adds rgb * f (per unit light) into out (rgb per cell, per direction).
void add_coloured(ColourField& out, const transport::SourceField& f, const glm::dvec3& rgb) {
    if (f.data.empty()) return;
    if (out.rgb.empty()) {
        out.geom = f.geom;
        out.directions = f.directions;
        out.rgb.assign(f.directions.size(), std::vector<float>(f.cells() * 3, 0.0f));
    }
    FULGUR_ASSERT(out.geom == f.geom && out.directions.size() == f.directions.size(),
                  "compose: the sun and the sky must share the lighting grid and directions");
    for (std::size_t m = 0; m < f.directions.size(); ++m) {
        const std::span<const float> v = f.direction(m);
        std::vector<float>& dst = out.rgb[m];
        for (std::size_t i = 0; i < v.size(); ++i)
            for (int c = 0; c < 3; ++c) dst[3 * i + std::size_t(c)] += float(rgb[c] * double(v[i]));
    }
}

void add_light(ColourField& out, const LightField& f, const glm::dvec3& rgb, bool single, bool multiple) {
    if (single) add_coloured(out, f.single, rgb);
    if (multiple) add_coloured(out, f.multiple, rgb);
}

}  // namespace

ColourField compose(const StaticLight& light, const std::optional<scene::Sun>& sun,
                    const std::optional<scene::SkyDome>& sky, const ComposeOptions& o) {
    ColourField out;
    if (o.sun && sun && light.sun)
        add_light(out, *light.sun, sun->irradiance * sun->colour, o.single && o.sun_single, o.multiple);
    if (o.sky && sky && light.sky) {
        add_light(out, light.sky->zenith, sky->zenith(), o.single, o.multiple);
        add_light(out, light.sky->horizon, sky->horizon(), o.single, o.multiple);
        add_light(out, light.sky->uniform, sky->zenith(), o.single, o.multiple);
    }
    return out;
}

namespace {

// The field of a unit sun along `direction`, every output direction of the scene.
LightField unit_sun_field(const scene::Scene& s, const solve::Media& media, const SolveSettings& settings,
                          const glm::dvec3& direction) {
    const transport::DirectionalSource unit{direction, 1.0};
    return solve_directional(media, std::span(&unit, 1),
                             transport::output_directions(static_direction_count(s, settings)), settings);
}

}  // namespace

SunSolve solve_sun(const scene::Scene& s, const core::Grid3<float>& density, const solve::Media& media,
                   const SolveSettings& settings, const glm::dvec3& direction) {
    core::Stopwatch sw;
    SunSolve out;
    out.direction = direction;
    out.field = unit_sun_field(s, media, settings, direction);
    out.transmittance = sun_transmittance(s, density, direction);
    out.seconds = sw.seconds();
    return out;
}

struct SunResolver::Impl {
    const scene::Scene& scene;
    const core::Grid3<float>& density;
    const solve::Media& media;
    SolveSettings settings;

    mutable std::mutex mu;
    std::optional<SunSolve> ready;
    std::exception_ptr error;
    std::atomic<std::uint64_t> generation{0};  // requests made so far
    core::Worker worker;                       // last: its jobs use the members above until it is joined

    Impl(const scene::Scene& s, const core::Grid3<float>& d, const solve::Media& m, const SolveSettings& st, int t)
        : scene(s), density(d), media(m), settings(st), worker(t) {}

    void publish(std::optional<SunSolve>&& result, std::exception_ptr e) {
        std::lock_guard<std::mutex> lock(mu);
        if (e)
            error = e;
        else
            ready = std::move(result);  // a newer finished solve replaces an untaken older one
    }

    void solve(const glm::dvec3& d, std::uint64_t request) {
        // A preview is the lattice's order 2 before the exact one; a Monte Carlo solve has no
        // cheaper first stage (its preview would be the same solve twice).
        const bool two_stage = settings.method != Method::MonteCarlo && settings.multiple && settings.exact_orders == 2;
        try {
            if (!two_stage) {
                publish(solve_sun(scene, density, media, settings, d), nullptr);
                return;
            }
            SolveSettings quick = settings;
            quick.exact_orders = 1;
            SunSolve preview = solve_sun(scene, density, media, quick, d);
            preview.preview = true;
            core::Grid3<float> transmittance = preview.transmittance;
            publish(std::move(preview), nullptr);
            if (generation.load() != request) return;  // the slider moved on: refine that one
            core::Stopwatch sw;
            SunSolve refined;
            refined.direction = d;
            refined.field = unit_sun_field(scene, media, settings, d);  // the preview's transmittance is this sun's
            refined.transmittance = std::move(transmittance);
            refined.seconds = sw.seconds();
            publish(std::move(refined), nullptr);
        } catch (...) {
            publish(std::nullopt, std::current_exception());
        }
    }
};

SunResolver::SunResolver(const scene::Scene& s, const core::Grid3<float>& density, const solve::Media& media,
                         const SolveSettings& settings, int threads)
    : impl_(std::make_unique<Impl>(s, density, media, settings, std::max(1, threads))) {}

SunResolver::~SunResolver() = default;

void SunResolver::request(const glm::dvec3& direction) {
    Impl& im = *impl_;
    const std::uint64_t request = ++im.generation;
    im.worker.submit([&im, direction, request] { im.solve(direction, request); }, /*latest_only=*/true);
}

std::optional<SunSolve> SunResolver::take() {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (impl_->error) {
        std::exception_ptr e = impl_->error;
        impl_->error = nullptr;
        std::rethrow_exception(e);
    }
    std::optional<SunSolve> out = std::move(impl_->ready);
    impl_->ready.reset();
    return out;
}

bool SunResolver::busy() const { return impl_->worker.busy(); }

double colour_error(const ColourField& x, const ColourField& ref, std::span<const float> density) {
    if (ref.empty()) return 0.0;
    FULGUR_ASSERT(x.rgb.size() == ref.rgb.size(), "colour_error: fields of different shapes");
    core::RelativeL2 e;
    for (std::size_t m = 0; m < ref.rgb.size(); ++m) {
        FULGUR_ASSERT(x.rgb[m].size() == ref.rgb[m].size() && ref.rgb[m].size() == 3 * density.size(),
                      "colour_error: fields of different shapes");
        for (std::size_t i = 0; i < ref.rgb[m].size(); ++i)
            if (density[i / 3] > 0.0f) e.add(double(x.rgb[m][i]), double(ref.rgb[m][i]));
    }
    return e.value();
}

}  // namespace fulgur::sky
