// NearField (near_field.h): the splat's near-field correction from a local model of each point.
#include "runtime/near_field.h"

#include "core/core.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <mutex>
#include <numbers>

namespace fulgur::runtime {

namespace {

constexpr double kInv4Pi = 0.25 / std::numbers::pi;

// Collided fluence per unit radiant intensity at distance r from an isotropic point source in
// an infinite homogeneous medium of extinction sigma (diffusion: D = 1 / (3 sigma_tr),
// L = sqrt(D / sigma_a)). A Monte Carlo of the same medium agrees within 2-8% at 0.1-10 free
// paths (docs/presets.md).
double diffusion_phi(double r, double sigma, double albedo, double g) {
    if (!(sigma > 1e-12) || !(r > 0.0)) return 0.0;
    const double D = 1.0 / (3.0 * sigma * (1.0 - albedo * g));
    const double L = std::sqrt(D / std::max(sigma * (1.0 - albedo), 1e-15));
    return std::exp(-r / L) / (D * r);
}

}  // namespace

struct NearField::Impl {
    transport::LightingMedium medium;
    basis::VirtualLightGrid lights;
    lightning::Splatter splatter;
    std::vector<glm::dvec3> dirs;
    NearFieldOptions options;
    std::vector<glm::dvec3> rays;
    std::vector<double> phase;  // [ray][m]
    double h = 0.0, reach = 0.0;
    std::size_t cells = 0;
    // The spread's neighbourhood: voxel offsets within `reach`, each with its squared length
    // in voxels, and diffusion's phi per squared length and mean density (kLevels + 1 levels
    // over [0, 1], linear between them: phi is smooth in the density).
    static constexpr int kLevels = 256;
    struct Offset {
        int di, dj, dk, n;
    };
    std::vector<Offset> offsets;
    std::vector<double> phi;  // [n][level]

    // A point's model at unit intensity on the cells it reaches: single per direction and the
    // scalar first-scattered source, as sparse lists.
    struct Kernel {
        std::vector<std::uint32_t> cell;
        std::vector<float> single;  // [k][m]
        std::vector<float> first;   // [k]
    };
    mutable std::vector<std::once_flag> made;
    mutable std::vector<Kernel> kept;
    mutable std::mutex count_mu;
    mutable std::size_t kept_count = 0;

    Impl(const transport::LightingMedium& m, const basis::VirtualLightGrid& l, std::span<const glm::dvec3> d,
         const NearFieldOptions& o)
        : medium(m),
          lights(l),
          splatter(lights),
          dirs(d.begin(), d.end()),
          options(o),
          rays(core::fibonacci_sphere(o.rays)),
          h(m.density.geom.voxel_size),
          reach(o.reach_voxels * m.density.geom.voxel_size),
          cells(m.density.geom.cell_count()),
          made(lights.count()),
          kept(lights.count()) {
        const double g = std::clamp(m.optics.g, -transport::kMaxAbsG, transport::kMaxAbsG);
        const int R = int(std::ceil(o.reach_voxels));
        int n_max = 0;
        for (int dk = -R; dk <= R; ++dk)
            for (int dj = -R; dj <= R; ++dj)
                for (int di = -R; di <= R; ++di) {
                    const int n = di * di + dj * dj + dk * dk;
                    if (double(n) > o.reach_voxels * o.reach_voxels) continue;
                    offsets.push_back({di, dj, dk, n});
                    n_max = std::max(n_max, n);
                }
        phi.resize(std::size_t(n_max + 1) * (kLevels + 1));
        for (int n = 0; n <= n_max; ++n)
            for (int lv = 0; lv <= kLevels; ++lv) {
                // Within one voxel: the mean 1/r of two uniform points in a cube, 1.8823 / h.
                const double r = n == 0 ? h / 1.8823 : h * std::sqrt(double(n));
                phi[std::size_t(n) * (kLevels + 1) + std::size_t(lv)] =
                    diffusion_phi(r, m.optics.extinction * lv / kLevels, m.optics.albedo, g);
            }
        phase.resize(rays.size() * dirs.size());
        for (std::size_t r = 0; r < rays.size(); ++r)
            for (std::size_t k = 0; k < dirs.size(); ++k)
                phase[r * dirs.size() + k] = transport::hg_phase(glm::dot(rays[r], dirs[k]), g);
    }

    // Hands the model of the point p at unit intensity to sink(i, j, k, cell, e, phase row) per ray
    // step in a cloud voxel (single scattering there: e x phase[m]; first-scattered: e / (4 pi)):
    // rays marched in steps of h / 8 out to `reach`, their last voxel ramped down linearly.
    template <class Sink>
    void cast(const glm::dvec3& p, Sink&& sink) const {
        const core::GridGeometry& geom = medium.density.geom;
        const std::vector<float>& rho = medium.density.data;
        const double kappa = medium.optics.extinction, albedo = medium.optics.albedo;
        const double dr = h / 8.0, d_omega = 4.0 * std::numbers::pi / double(rays.size());
        const double scale = albedo * dr * d_omega / (h * h * h), ramp_from = reach - h;
        const std::size_t nd = dirs.size();
        for (std::size_t r = 0; r < rays.size(); ++r) {
            const glm::dvec3 u = rays[r];
            const double* ph = &phase[r * nd];
            double tau = 0.0;
            for (double r0 = 0.0; r0 < reach; r0 += dr) {
                const double rm = r0 + 0.5 * dr;
                const glm::dvec3 v = geom.to_voxel(p + u * rm);
                const int i = int(std::floor(v.x)), j = int(std::floor(v.y)), k = int(std::floor(v.z));
                if (i < 0 || j < 0 || k < 0 || i >= geom.dims.x || j >= geom.dims.y || k >= geom.dims.z) break;
                const std::size_t c = geom.index(i, j, k);
                const double sigma = kappa * double(rho[c]);
                const double tau_mid = tau + 0.5 * sigma * dr;
                tau += sigma * dr;
                if (!(rho[c] > 0.0f)) continue;
                sink(i, j, k, c, scale * std::exp(-tau_mid) * (rm > ramp_from ? (reach - rm) / h : 1.0), ph);
            }
        }
    }
    // A point's model at unit intensity: summed in a box of voxels around it (its support),
    // then kept as a sparse list of the voxels it reaches.
    Kernel model(const glm::dvec3& p) const {
        const core::GridGeometry& geom = medium.density.geom;
        const glm::dvec3 v = geom.to_voxel(p);
        const int R = int(std::ceil(reach / h)) + 1, side = 2 * R + 1;
        const core::Int3 lo{int(std::floor(v.x)) - R, int(std::floor(v.y)) - R, int(std::floor(v.z)) - R};
        const std::size_t nd = dirs.size(), box = std::size_t(side) * side * side;
        // Scratch kept per thread: fresh ~0.3 MB arrays per point were page faults each time.
        thread_local std::vector<double> single, first;
        thread_local std::vector<std::uint32_t> cell;
        single.assign(box * nd, 0.0);
        first.assign(box, 0.0);
        cell.assign(box, 0);
        cast(p, [&](int i, int j, int k, std::size_t c, double e, const double* ph) {
            const std::size_t b =
                std::size_t(i - lo.x) +
                std::size_t(side) * (std::size_t(j - lo.y) + std::size_t(side) * std::size_t(k - lo.z));
            cell[b] = std::uint32_t(c);
            for (std::size_t m = 0; m < nd; ++m) single[b * nd + m] += e * ph[m];
            first[b] += e * kInv4Pi;
        });
        Kernel k;
        for (std::size_t b = 0; b < box; ++b) {
            if (first[b] == 0.0) continue;
            k.cell.push_back(cell[b]);
            k.first.push_back(float(first[b]));
            for (std::size_t m = 0; m < nd; ++m) k.single.push_back(float(single[b * nd + m]));
        }
        return k;
    }

    // A light's model, made once and kept.
    const Kernel& light(std::uint32_t l) const {
        std::call_once(made[l], [&] {
            kept[l] = model(lights.position(l));
            std::lock_guard<std::mutex> lock(count_mu);
            ++kept_count;
        });
        return kept[l];
    }

    // Adds w x the model k: its single scattering to `single` ([m][cell], float: a few dozen
    // terms per voxel), its first-scattered source to `first`.
    void accumulate(const Kernel& k, double w, std::vector<float>& single, std::vector<double>& first) const {
        const std::size_t nd = dirs.size();
        const float wf = float(w);
        for (std::size_t n = 0; n < k.cell.size(); ++n) {
            const std::size_t c = k.cell[n];
            first[c] += w * double(k.first[n]);
            const float* ks = &k.single[n * nd];
            for (std::size_t m = 0; m < nd; ++m) single[m * cells + c] += wf * ks[m];
        }
    }

    // The first-scattered source's multiple scattering (the same in every direction): emission
    // 4 pi sigma_t S1 per volume spread by diffusion's Green's function phi / (4 pi) between
    // voxel centres, the extinction the mean of the two voxels'.
    void spread(const std::vector<double>& first, std::vector<double>& multiple) const {
        const core::GridGeometry& geom = medium.density.geom;
        const std::vector<float>& rho = medium.density.data;
        const double V = h * h * h, kappa = medium.optics.extinction, albedo = medium.optics.albedo;
        for (std::size_t y = 0; y < cells; ++y) {
            if (first[y] == 0.0) continue;
            const core::Int3 p = geom.unindex(y);
            const double emitted = albedo * kInv4Pi * kappa * double(rho[y]) * first[y] * V;
            for (const Offset& o : offsets) {
                const int i = p.x + o.di, j = p.y + o.dj, k = p.z + o.dk;
                if (i < 0 || j < 0 || k < 0 || i >= geom.dims.x || j >= geom.dims.y || k >= geom.dims.z) continue;
                const std::size_t x = geom.index(i, j, k);
                if (!(rho[x] > 0.0f)) continue;
                const double level = 0.5 * (double(rho[y]) + double(rho[x])) * kLevels;
                const int l0 = std::min(int(level), kLevels - 1);
                const double f = level - l0;
                const double* row = &phi[std::size_t(o.n) * (kLevels + 1) + std::size_t(l0)];
                multiple[x] += emitted * (row[0] + f * (row[1] - row[0]));
            }
        }
    }
};

std::vector<transport::PointSource> lit_sources(std::span<const transport::PointSource> sources) {
    std::vector<transport::PointSource> lit;
    lit.reserve(sources.size());
    for (const transport::PointSource& q : sources)
        if (std::isfinite(q.position.x) && std::isfinite(q.position.y) && std::isfinite(q.position.z) &&
            std::isfinite(q.intensity) && q.intensity != 0.0)
            lit.push_back(q);
    return lit;
}

NearField::NearField(const transport::LightingMedium& lighting, const basis::VirtualLightGrid& lights,
                     std::span<const glm::dvec3> directions, const NearFieldOptions& options) {
    FULGUR_ASSERT(options.rays >= 1 && options.rays <= 65536, "NearField: rays must be in [1, 65536]");
    FULGUR_ASSERT(options.reach_voxels >= 1.0 && options.reach_voxels <= 64.0,
                  "NearField: reach_voxels must be in [1, 64]");
    FULGUR_ASSERT(!directions.empty(), "NearField: no output directions");
    impl_ = std::make_unique<Impl>(lighting, lights, directions, options);
}

NearField::~NearField() = default;

std::size_t NearField::kept_lights() const {
    std::lock_guard<std::mutex> lock(impl_->count_mu);
    return impl_->kept_count;
}
std::size_t NearField::cells() const noexcept { return impl_->cells; }
std::size_t NearField::light_count() const noexcept { return impl_->kept.size(); }
void NearField::keep_light(std::size_t l) const {
    FULGUR_ASSERT(l < impl_->kept.size(), "NearField::keep_light: no such light");
    impl_->light(std::uint32_t(l));
}
std::size_t NearField::directions() const noexcept { return impl_->dirs.size(); }

void NearField::add(std::span<const transport::PointSource> sources, NearFieldParts& out) const {
    const Impl& im = *impl_;
    const std::size_t nd = im.dirs.size(), cells = im.cells;
    FULGUR_ASSERT(out.empty() || (out.single.size() == nd * cells && out.multiple.size() == nd * cells),
                  "NearField::add: the parts are not [directions][cells]");
    const std::vector<transport::PointSource> finite = lit_sources(sources);
    if (finite.empty()) return;
    if (out.empty()) {
        out.single.assign(nd * cells, 0.0f);
        out.multiple.assign(nd * cells, 0.0f);
    }
    // The points' models in parallel (each its own), then summed in a fixed order: the same
    // field on any number of threads.
    std::vector<Impl::Kernel> models(finite.size());
    core::parallel_for_dynamic(0, std::int64_t(finite.size()), [&](std::int64_t i) {
        models[std::size_t(i)] = im.model(finite[std::size_t(i)].position);
    });
    std::vector<double> first(cells, 0.0);
    for (std::size_t i = 0; i < finite.size(); ++i) im.accumulate(models[i], finite[i].intensity, out.single, first);
    lightning::LightWeights w;
    im.splatter.splat(finite, w);
    for (const std::uint32_t l : w.active) im.accumulate(im.light(l), -w.e[l], out.single, first);
    if (!im.options.multiple) return;
    std::vector<double> multiple(cells, 0.0);
    im.spread(first, multiple);
    for (std::size_t m = 0; m < nd; ++m)
        for (std::size_t c = 0; c < cells; ++c) out.multiple[m * cells + c] += float(multiple[c]);
}

std::vector<transport::PointSource> NearField::stroke_sources(const lightning::Bolt& bolt, std::size_t group) const {
    lightning::FlashState unit;
    (group == 0 ? unit.main_glow : unit.branch_glow) = 1.0;
    std::vector<lightning::LitSegment> lit;
    lightning::lit_segments(bolt, unit, lit);
    std::vector<transport::PointSource> sources;
    lightning::append_point_sources(lit, impl_->splatter.source_spacing(), sources);
    return sources;
}

NearFieldParts NearField::strokes(const lightning::Bolt& bolt, std::size_t group) const {
    const std::vector<transport::PointSource> sources = stroke_sources(bolt, group);
    NearFieldParts parts;
    if (!sources.empty()) add(sources, parts);
    return parts;
}

}  // namespace fulgur::runtime
