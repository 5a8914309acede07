// The refined transport grid (transport.refine): the solvers run on the lighting grid
// refined r times and S is averaged back. On a homogeneous sphere and a slab whose lighting
// voxels have hop optical depths 0.5, 2 and 8, solve::solve's multiple scattering at refine 1
// and 4 against the truth (Monte Carlo through the full-resolution medium, tallied on the
// lighting grid); energy bookkeeping and finite, bounded values on the refined lattice.
#include "bake/bake.h"

#include "transport/transport.h"

#include <doctest/doctest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

using namespace fulgur;

namespace {

constexpr int kFine = 48, kDown = 4;  // 48^3 fine voxels, 12^3 lighting voxels
constexpr double kH = 100.0;          // fine voxel, m

enum class Shape { Sphere, Slab };

core::Grid3<float> shape_density(Shape shape) {
    core::GridGeometry g;
    g.dims = {kFine, kFine, kFine};
    g.voxel_size = kH;
    core::Grid3<float> d(g, 0.0f);
    const glm::dvec3 c = g.origin + 0.5 * g.extent();
    for (int k = 0; k < kFine; ++k)
        for (int j = 0; j < kFine; ++j)
            for (int i = 0; i < kFine; ++i) {
                const glm::dvec3 x = g.centre(i, j, k);
                const bool in = shape == Shape::Sphere ? glm::length(x - c) < 0.4 * kFine * kH
                                                       : (k >= kFine / 4 && k < 3 * kFine / 4);
                d.at(i, j, k) = in ? 1.0f : 0.0f;
            }
    return d;
}

struct Case {
    Shape shape;
    double tau;  // optical depth of one lighting voxel's hop
    const char* name() const { return shape == Shape::Sphere ? "sphere" : "slab"; }
};

struct Result {
    double l2 = 0.0, ratio = 0.0;  // multiple part against the truth, over the medium's voxels
    double most_negative = 0.0;    // min / max of the multiple part
    bool finite = true;
};

// The light: at the sphere's centre, or 1.2 km below the slab.
glm::dvec3 light_position(Shape shape) {
    const double mid = 0.5 * kFine * kH;
    return shape == Shape::Sphere ? glm::dvec3(mid + 37.0, mid - 21.0, mid + 13.0)
                                  : glm::dvec3(mid + 37.0, mid - 21.0, 0.25 * kFine * kH - 1200.0);
}

// The truth of case c: Monte Carlo through the full-resolution medium, tallied on the
// lighting grid (it does not depend on the transport grid's refinement, so each case traces it
// once for both solves).
transport::MonteCarloResult truth_of(const Case& c, const core::Grid3<float>& density, const transport::Medium& optics,
                                     const core::GridGeometry& lighting, const std::vector<glm::dvec3>& dirs) {
    transport::LightingMedium fine;
    fine.density = density;
    fine.optics = optics;
    transport::MonteCarloOptions o;
    o.paths = 60'000;
    o.batches = 8;
    o.seed = 17;
    const transport::PointSource p{light_position(c.shape), 1.0};
    return transport::monte_carlo(fine, std::span(&p, 1), {}, lighting, dirs, o);
}

scene::Scene case_scene(const Case& c, int refine) {
    scene::Scene s;
    s.medium = {c.tau / (kDown * kH), 0.99, 0.6};  // sigma_t at density 1: tau per lighting voxel
    s.lighting_downsample = kDown;
    s.transport.refine = refine;
    return s;
}

// solve::solve's multiple part at `refine` against the truth, compared on the lighting grid.
Result run(const Case& c, int refine, const core::Grid3<float>& density, const transport::MonteCarloResult& truth,
           const std::vector<glm::dvec3>& dirs) {
    const scene::Scene s = case_scene(c, refine);
    solve::Media media;
    media.lighting.density = core::downsample(density, kDown);
    media.lighting.optics = s.medium;
    media.transport.density = core::downsample(density, kDown / refine);
    media.transport.optics = s.medium;
    media.refine = refine;
    const transport::PointSource p{light_position(c.shape), 1.0};
    const solve::Solution sol = solve::solve(s, media, std::span(&p, 1), dirs);

    Result r;
    core::RelativeL2 e;
    double sum = 0.0, sum_ref = 0.0, lo = 0.0, hi = 0.0;
    const std::vector<float>& rho = media.lighting.density.data;
    for (std::size_t i = 0; i < sol.multiple.data.size(); ++i) {
        const float v = sol.multiple.data[i];
        r.finite = r.finite && std::isfinite(v);
        lo = std::min(lo, double(v));
        hi = std::max(hi, double(v));
        if (!(rho[i % rho.size()] > 0.0f)) continue;
        e.add(v, truth.multiple.data[i]);
        sum += v;
        sum_ref += truth.multiple.data[i];
    }
    r.l2 = e.value();
    r.ratio = sum / sum_ref;
    r.most_negative = lo / hi;
    return r;
}

}  // namespace

TEST_CASE("refined transport grid: thick lighting voxels against the truth") {
    // Measured relative L2 of the multiple part (sum ratio) at refine 1 -> refine 4:
    //   sphere, light inside: tau 0.5: 0.38 (0.93) -> 0.32 (0.99); tau 2: 0.42 (0.85) -> 0.12
    //   (0.98); tau 8: 0.90 (0.31) -> 0.10 (0.98);
    //   slab, light 1.2 km below: tau 0.5: 0.22 (1.01) -> 0.23 (1.07); tau 2: 0.26 (0.96) ->
    //   0.13 (1.07); tau 8: 0.77 (0.45) -> 0.089 (1.04).
    // The refined lattice fixes thick voxels (refine 1 keeps a third of the light at tau 8);
    // in thin ones (tau 0.5) both are limited by the lattice's 18 directions, not by the
    // voxel size. Bounds ~25% above the refined measurements (the truth's noise at 6e4 paths
    // is 1-3%); ratio bands +-15%; and the refined lattice must be at least 1.5 times as close
    // to the truth as the coarse one at tau 2, 4 times at tau 8.
    struct Bound {
        Case c;
        double l2;
    };
    const std::vector<Bound> bounds = {{{Shape::Sphere, 0.5}, 0.40}, {{Shape::Sphere, 2.0}, 0.16},
                                       {{Shape::Sphere, 8.0}, 0.14}, {{Shape::Slab, 0.5}, 0.29},
                                       {{Shape::Slab, 2.0}, 0.17},   {{Shape::Slab, 8.0}, 0.11}};
    for (const Bound& b : bounds) {
        const std::string name = b.c.name();
        CAPTURE(name);
        CAPTURE(b.c.tau);
        const core::Grid3<float> density = shape_density(b.c.shape);
        const std::vector<glm::dvec3> dirs = transport::output_directions(26);
        const transport::MonteCarloResult truth =
            truth_of(b.c, density, case_scene(b.c, 1).medium, core::downsample(density, kDown).geom, dirs);
        const Result coarse = run(b.c, 1, density, truth, dirs), fine = run(b.c, 4, density, truth, dirs);
        MESSAGE(name << " tau " << b.c.tau << ": refine 1 " << coarse.l2 << " (ratio " << coarse.ratio << "), refine 4 "
                     << fine.l2 << " (ratio " << fine.ratio << "), most negative " << fine.most_negative);
        CHECK(fine.finite);
        CHECK(fine.l2 < b.l2);
        CHECK(fine.ratio > 0.85);
        CHECK(fine.ratio < 1.15);
        if (b.c.tau >= 2.0) CHECK(coarse.l2 > (b.c.tau >= 8.0 ? 4.0 : 1.5) * fine.l2);
        // Over-relaxed sites may dip below zero (docs/lattice-boltzmann.md "Negative values"):
        // at most 0.5% of the maximum, as on the storm (0.4%).
        CHECK(fine.most_negative > -0.005);
    }
}
