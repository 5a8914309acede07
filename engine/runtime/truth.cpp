// The truth (runtime.h): Monte Carlo of a frame's lit channel through the full-resolution
// density, S tallied on the lighting grid with a noise estimate.
#include "runtime/runtime.h"
#include "sky/sky.h"

#include <utility>

namespace fulgur::runtime {

transport::SourceField Truth::sum(const Components& c) const {
    transport::SourceField out(single.geom, single.directions);
    for (std::size_t i = 0; i < out.data.size(); ++i)
        out.data[i] = (c.single ? single.data[i] : 0.0f) + (c.multiple ? multiple.data[i] : 0.0f);
    return out;
}

transport::SourceField Truth::rain_light(const scene::Scene& scene, const Components& drawn) const {
    const double albedo = scene.medium.albedo;
    if (!(scene.rain && drawn.multiple && albedo > 0.0)) return {};
    transport::SourceField out = multiple;
    for (float& v : out.data) v = float(double(v) / albedo);
    return out;
}

Truth truth(const scene::Scene& scene, const core::Grid3<float>& density, std::span<const lightning::LitSegment> lit,
            std::span<const transport::PointSource> points, const TruthOptions& options) {
    // With rain, the medium the presets' traced strike solves see (FramePipeline): the rain at
    // its own extinction, scattering as drops (solve::Media::traced), S at its points with the
    // drops' phase function.
    std::optional<solve::Media> wet;
    if (scene.rain) wet = sky::make_static_media(scene, density, 1, true);
    transport::LightingMedium fine;
    if (wet) {
        fine = std::move(wet->traced);
    } else {
        fine.density = density;
        fine.optics = scene.medium;
    }
    core::GridGeometry lighting = density.geom;
    const int f = scene.lighting_downsample;
    lighting.voxel_size *= f;
    lighting.dims = {(density.dims().x + f - 1) / f, (density.dims().y + f - 1) / f, (density.dims().z + f - 1) / f};
    const std::vector<transport::PointSource> pts(points.begin(), points.end());
    std::vector<transport::LineSource> lines;
    for (const lightning::LitSegment& s : lit) lines.push_back({s.a, s.b, s.intensity});
    transport::MonteCarloOptions mc;
    mc.paths = options.paths;
    mc.batches = options.batches;
    mc.seed = options.seed;
    mc.halves = true;
    mc.tally_weight = options.weight;
    mc.tally_multiple = options.multiple;
    if (!options.multiple) mc.max_scatterings = 0;
    const std::vector<glm::dvec3> dirs = transport::output_directions(scene.effective_directions());
    mc.toward = options.toward;
    mc.ground = options.multiple ? options.ground : std::nullopt;  // scattered light: the paths must go on
    if (wet) mc.phase_mix = wet->lighting.phase_mix.get();
    transport::MonteCarloResult r =
        transport::monte_carlo(fine, pts, lines, lighting, options.toward ? transport::output_directions(1) : dirs, mc);
    Truth t;
    t.single = std::move(r.single);
    t.multiple = std::move(r.multiple);
    if (options.toward)  // the one field in every direction, as a strike solved toward the camera
        for (transport::SourceField* field : {&t.single, &t.multiple})
            *field = transport::in_every_direction(*field, dirs);
    t.noise = r.noise;
    t.sums = r.sums;
    t.ground = std::move(r.ground);
    t.ground_power = r.ground_power;
    t.paths = r.paths;
    t.seconds = r.seconds;
    return t;
}

}  // namespace fulgur::runtime
