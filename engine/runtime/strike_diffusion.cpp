// StrikeDiffusion (strike_diffusion.h): a strike's own light, single scattering by its points'
// rays and multiple scattering by flux-limited diffusion, in place of the bases'.
#include "runtime/strike_diffusion.h"

#include "core/core.h"
#include "lightning/lightning.h"
#include "runtime/reconstructor.h"

#include <array>
#include <atomic>
#include <cmath>
#include <vector>

namespace fulgur::runtime {

struct StrikeDiffusion::Impl {
    transport::LightingMedium medium;
    const transport::LightingMedium* full;  // null, or the density at full resolution
    const BakedBases& bases;
    lightning::Splatter splatter;
    std::vector<glm::dvec3> dirs;
    StrikeDiffusionOptions options;
    bool separable = false;
    mutable std::atomic<int> iterations{0};
    mutable std::atomic<bool> converged{true};

    Impl(const transport::LightingMedium& m, const transport::LightingMedium* f, const BakedBases& b,
         std::span<const glm::dvec3> d, const StrikeDiffusionOptions& o)
        : medium(m),
          full(o.fine_rays > 0 ? f : nullptr),
          bases(b),
          splatter(b.lights()),
          dirs(d.begin(), d.end()),
          options(o) {
        // Only separate bases can show the multiple part alone; a bake without it shows none
        // (the correction then adds the whole solve).
        separable = (b.separate() || !b.has_multiple()) && b.lighting() == m.density.geom &&
                    b.directions().size() == dirs.size();
    }
};

StrikeDiffusion::StrikeDiffusion(const transport::LightingMedium& lighting, const BakedBases& bases,
                                 std::span<const glm::dvec3> directions, const StrikeDiffusionOptions& options,
                                 const transport::LightingMedium* full) {
    FULGUR_ASSERT(options.rays >= 1 && options.rays <= 65536, "StrikeDiffusion: rays must be in [1, 65536]");
    FULGUR_ASSERT(options.fine_rays >= 0 && options.fine_rays <= 65536,
                  "StrikeDiffusion: fine_rays must be in [0, 65536]");
    FULGUR_ASSERT(!directions.empty(), "StrikeDiffusion: no output directions");
    FULGUR_ASSERT(bases.lights().count() > 0, "StrikeDiffusion: bases without lights");
    impl_ = std::make_unique<Impl>(lighting, full, bases, directions, options);
}

StrikeDiffusion::~StrikeDiffusion() = default;

bool StrikeDiffusion::separable() const noexcept { return impl_->separable; }
bool StrikeDiffusion::replaces_single() const noexcept { return impl_->options.single; }
int StrikeDiffusion::last_iterations() const noexcept { return impl_->iterations.load(); }
bool StrikeDiffusion::last_converged() const noexcept { return impl_->converged.load(); }

bool StrikeDiffusion::add(std::span<const transport::PointSource> sources, NearFieldParts& out) const {
    const Impl& im = *impl_;
    if (!im.separable) return false;
    const std::size_t nd = im.dirs.size(), cells = im.medium.density.geom.cell_count();
    FULGUR_ASSERT(out.empty() || (out.single.size() == nd * cells && out.multiple.size() == nd * cells),
                  "StrikeDiffusion::add: the parts are not [directions][cells]");
    const std::vector<transport::PointSource> finite = lit_sources(sources);
    if (finite.empty()) return false;

    // The bases' parts of the points' splat that this replaces: what the bases' frame shows.
    lightning::LightWeights w;
    im.splatter.splat(finite, w);
    Reconstructor rec(im.bases);
    std::array<RadianceField, 2> splatted;
    std::array<bool, 2> have_bases = {false, false};
    for (const int part : {0, 1}) {
        if (part == 0 && !im.options.single) continue;
        ReconstructOptions ro;
        ro.components = {part == 0, part == 1};
        StageTimes st;
        have_bases[std::size_t(part)] = rec.reconstruct(w, {}, ro, splatted[std::size_t(part)], st);
    }

    std::vector<double> emission, single;
    const core::GridGeometry& lg = im.medium.density.geom;
    if (im.options.single && im.full) {
        std::vector<double> fine_emission;
        transport::add_point_scattering_fine(*im.full, lg, finite, im.options.fine_rays, im.options.seed, im.dirs,
                                             fine_emission, single, &im.medium.density);
        if (im.options.fine_emission)
            emission = std::move(fine_emission);
        else
            transport::add_first_scattered_emission(im.medium, finite, im.options.rays, im.options.seed, emission);
    } else if (im.options.single) {
        transport::add_point_scattering(im.medium, finite, im.options.rays, im.options.seed, im.dirs, emission, single);
    } else {
        transport::add_first_scattered_emission(im.medium, finite, im.options.rays, im.options.seed, emission);
    }
    const transport::DiffusionField field = transport::solve_diffusion(im.medium, emission, im.options.diffusion);
    im.iterations.store(field.iterations);
    im.converged.store(field.converged);

    if (out.empty()) {
        out.single.assign(nd * cells, 0.0f);
        out.multiple.assign(nd * cells, 0.0f);
    }
    transport::add_diffusion_source(im.medium, field, im.dirs, 1.0, out.multiple);
    for (std::size_t i = 0; i < single.size(); ++i) out.single[i] += float(single[i]);
    for (const std::size_t part : {0u, 1u}) {
        if (!have_bases[part]) continue;
        std::vector<float>& to = part == 0 ? out.single : out.multiple;
        const RadianceField& r = splatted[part];
        for (std::size_t k = 0; k < r.directions.size(); ++k) {
            const std::size_t m = std::size_t(r.directions[k]);
            const std::vector<float>& v = r.values[k];
            for (std::size_t c = 0; c < cells; ++c) to[m * cells + c] -= v[c];
        }
    }
    return true;
}

}  // namespace fulgur::runtime
