// A near-field correction of the splat, as particle-particle particle-mesh methods split a
// force: the bases carry what the splat represents at its spacing; what it cannot (the fast
// variation next to the channel) is added per strike as the difference of a local model between
// each of the frame's point sources and the virtual lights it was splatted onto,
//   S ~ sum_l e_l B_l + sum_q ( K[q] - sum_l w_ql K[l] ),
// on the lighting voxels within `reach` of q. Where the model is exact this replaces the splat's
// near field by the model's; beyond a few spacings the two terms cancel (the trilinear weights
// keep the source's position), so the bases keep the far field.
//   near-field: the default storm's strikes 1-5, dusk-storm's and vdb-cloud's 1-3, each at its
//   first return stroke + 2 ms, against the truth, single and multiple scattering apart, for the models
//     single: a I p(cos) T / r^2 per output direction (exact single scattering of a point on the
//       lighting grid's density);
//     multiple, point kernel: the collided fluence of a point source in a homogeneous medium by
//       diffusion, phi = I exp(-r / L) / (D r), with the extinction averaged along the path
//       (D = 1 / (3 sigma_tr), L = sqrt(D / sigma_a)); S = a phi / (4 pi);
//     multiple, transport kernel: the same with the collided fluence tabulated by Monte Carlo in
//       the homogeneous medium instead of diffusion (whether diffusion's shape is what fails);
//     multiple, first-scattered: the single model's scalar first-scattered source (what the
//       light injects into the cloud, so a channel below the base lights the base where it
//       meets it) spread over the voxels around it by the same diffusion Green's function;
//   each by rays cast from the point (the 1/r^2 and 1/r singularities cancel against the ray
//   bundle's r^2 dr dOmega), at 32, 128, 512 and 2048 rays: the knob that trades accuracy for
//   time. Then the same corrections on perfect bases (the splatted virtual lights traced by the
//   truth's Monte Carlo in place of the lattice's bases): what the models leave when the bases
//   are exact.
//   Outputs: near_field.csv (one row per strike and candidate; seconds: one thread, the engine's
//   runtime::NearField rows on every thread with the lights' models kept).
#include "study/study.h"

#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>

using namespace fulgur;

namespace {

// Collided fluence per unit radiant intensity at distance r from an isotropic point source in
// an infinite homogeneous medium of extinction sigma (diffusion approximation).
double diffusion_phi(double r, double sigma, double albedo, double g) {
    if (sigma <= 1e-9) return 0.0;
    const double D = 1.0 / (3.0 * sigma * (1.0 - albedo * g));
    const double L = std::sqrt(D / std::max(sigma * (1.0 - albedo), 1e-12));
    return std::exp(-r / L) / (D * r);
}

// The collided fluence (orders >= 1) of a unit-intensity isotropic point source in an infinite
// homogeneous medium of unit extinction, by Monte Carlo with the collision estimator (the
// collision density of scattered light is sigma_t phi), on log-spaced shells in optical
// distance; F(tau) for extinction sigma is sigma^2 F(sigma r). Deterministic per seed.
class TransportKernel {
public:
    TransportKernel(double albedo, double g, std::uint64_t photons) {
        constexpr int bins = 96;
        constexpr double lo = 1e-3, hi = 60.0;
        edges_.resize(bins + 1);
        for (int b = 0; b <= bins; ++b) edges_[std::size_t(b)] = lo * std::pow(hi / lo, double(b) / bins);
        std::vector<double> tally(bins, 0.0);
        core::Rng rng(core::hash_seed(0x6e656172u, photons));
        const double w0 = 4.0 * std::numbers::pi / double(photons);
        for (std::uint64_t n = 0; n < photons; ++n) {
            const double z = 1.0 - 2.0 * rng.uniform(), ph = 2.0 * std::numbers::pi * rng.uniform();
            const double rr = std::sqrt(std::max(0.0, 1.0 - z * z));
            glm::dvec3 d(rr * std::cos(ph), rr * std::sin(ph), z);
            glm::dvec3 p = d * -std::log(1.0 - rng.uniform());
            double w = w0 * albedo;  // the first collision is the uncollided light's
            d = transport::hg_sample(d, g, rng.uniform(), rng.uniform());
            while (w > 1e-5 * w0) {
                p += d * -std::log(1.0 - rng.uniform());
                const double r = glm::length(p);
                if (r >= hi) break;
                if (r >= lo) {
                    const int b = int(std::log(r / lo) / std::log(hi / lo) * bins);
                    tally[std::size_t(std::clamp(b, 0, bins - 1))] += w;
                }
                w *= albedo;
                d = transport::hg_sample(d, g, rng.uniform(), rng.uniform());
            }
        }
        phi_.resize(bins);
        centre_.resize(bins);
        for (int b = 0; b < bins; ++b) {
            const double a = edges_[std::size_t(b)], c = edges_[std::size_t(b) + 1];
            phi_[std::size_t(b)] = tally[std::size_t(b)] / (4.0 / 3.0 * std::numbers::pi * (c * c * c - a * a * a));
            centre_[std::size_t(b)] = std::sqrt(a * c);
        }
    }
    // F(tau): interpolated linearly in log-log between shell centres; ~1/tau below the first.
    double operator()(double tau) const {
        if (tau <= centre_.front()) return phi_.front() * centre_.front() / std::max(tau, 1e-9);
        if (tau >= centre_.back()) return 0.0;
        const auto it = std::upper_bound(centre_.begin(), centre_.end(), tau);
        const std::size_t b = std::size_t(it - centre_.begin()) - 1;
        const double f = std::log(tau / centre_[b]) / std::log(centre_[b + 1] / centre_[b]);
        const double y0 = std::max(phi_[b], 1e-30), y1 = std::max(phi_[b + 1], 1e-30);
        return std::exp(std::log(y0) + f * (std::log(y1) - std::log(y0)));
    }

private:
    std::vector<double> edges_, centre_, phi_;
};

// The near-field models' fields on the lighting grid: single per output direction
// (direction-major), the point kernel's multiple and the scalar first-scattered source.
struct NearField {
    std::vector<double> single, multiple, first_scattered, transport_multiple;
};

}  // namespace

FULGUR_STUDY(near_field, "near-field",
             "the splat with a near-field correction (the difference of a local model between each point source "
             "and the virtual lights it is splatted onto): exact single scattering of points, and two diffusion "
             "models of multiple scattering, at three ray counts and on perfect bases, against the truth (default "
             "storm, 5 strikes; dusk-storm and vdb-cloud, 3)") {
    const std::vector<study::StrikeCase> cases = study::strike_cases(ctx.quick);
    study::Csv rows(ctx.file("near_field.csv"), {"scene", "seed", "candidate", "rays", "single_error", "multiple_error",
                                                 "total_error", "seconds", "source_seconds"});
    nlohmann::json worst = nlohmann::json::object();
    for (const study::StrikeCase& sc : cases) {
        const study::StrikeScene storm = study::strike_scene(sc.file);
        const auto& [s, density, bases, media] = storm;
        const transport::LightingMedium& lm = media.lighting;
        const std::vector<float>& rho = lm.density.data;
        const core::GridGeometry& geom = lm.density.geom;
        const std::size_t cells = rho.size();
        const double h = geom.voxel_size, V = h * h * h;
        const double kappa = lm.optics.extinction, albedo = lm.optics.albedo, g = lm.optics.g;
        const std::uint64_t truth_paths = ctx.quick ? 300'000 : 1'000'000;
        const int strikes = sc.strikes;
        // Four lighting voxels (3 km at the storm's 750 m): 6 moved no figure by more than 0.001.
        const double reach = 4.0 * h;
        const double inv4pi = 0.25 / std::numbers::pi;
        const auto tk0 = std::chrono::steady_clock::now();
        const TransportKernel kernel(albedo, g, ctx.quick ? 50'000 : 200'000);
        std::fprintf(stderr,
                     "near-field: transport kernel tabulated in %.2f s; F(0.1) %.4g F(1) %.4g F(3) %.4g F(10) %.4g\n",
                     study::seconds_since(tk0), kernel(0.1), kernel(1.0), kernel(3.0), kernel(10.0));

        // Adds sign x both models of the point (q, I) to `out` on the cells `mask` admits, by
        // `rays` rays marched in steps of h / 8 out to r_max.
        auto cast = [&](const glm::dvec3& q, double I, double sign, double r_max, const std::vector<char>& mask,
                        std::span<const glm::dvec3> rays, std::span<const glm::dvec3> dirs, NearField& out,
                        double taper_from = std::numeric_limits<double>::infinity()) {
            const double dr = h / 8.0, d_omega = 4.0 * std::numbers::pi / double(rays.size());
            std::vector<double> ph(dirs.size());
            for (const glm::dvec3& u : rays) {
                for (std::size_t m = 0; m < dirs.size(); ++m) ph[m] = transport::hg_phase(glm::dot(u, dirs[m]), g);
                double tau = 0.0;
                for (double r0 = 0.0; r0 < r_max; r0 += dr) {
                    const double rm = r0 + 0.5 * dr;
                    const glm::dvec3 v = geom.to_voxel(q + u * rm);
                    const int i = int(std::floor(v.x)), j = int(std::floor(v.y)), k = int(std::floor(v.z));
                    if (i < 0 || j < 0 || k < 0 || i >= geom.dims.x || j >= geom.dims.y || k >= geom.dims.z) break;
                    const std::size_t c = geom.index(i, j, k);
                    const double sig = kappa * double(rho[c]);
                    const double tau_mid = tau + 0.5 * sig * dr;
                    tau += sig * dr;
                    if (!mask[c] || rho[c] <= 0.0f) continue;
                    const double w = sign * I * albedo * dr * d_omega / V *
                                     (rm > taper_from ? (r_max - rm) / (r_max - taper_from) : 1.0);
                    const double e1 = w * std::exp(-tau_mid);
                    for (std::size_t m = 0; m < dirs.size(); ++m) out.single[m * cells + c] += e1 * ph[m];
                    out.first_scattered[c] += e1 * inv4pi;
                    out.multiple[c] += w * inv4pi * diffusion_phi(rm, tau_mid / rm, albedo, g) * rm * rm;
                    const double sig_path = tau_mid / rm;
                    out.transport_multiple[c] += w * inv4pi * sig_path * sig_path * kernel(sig_path * rm) * rm * rm;
                }
            }
        };
        // The correction of every source: K[q] - sum_l w_ql K[l] on the cells within `reach` of q.
        const lightning::Splatter splatter(bases.lights());
        double source_seconds = 0.0;  // of the last correction: the sources' own casts
        auto correction = [&](std::span<const transport::PointSource> src, std::span<const glm::dvec3> rays,
                              std::span<const glm::dvec3> dirs) {
            source_seconds = 0.0;
            NearField f{std::vector<double>(cells * dirs.size(), 0.0), std::vector<double>(cells, 0.0),
                        std::vector<double>(cells, 0.0), std::vector<double>(cells, 0.0)};
            std::vector<char> mask(cells);
            lightning::LightWeights w;
            for (const transport::PointSource& q : src) {
                if (q.intensity == 0.0) continue;
                for (std::size_t c = 0; c < cells; ++c) {
                    const core::Int3 x = geom.unindex(c);
                    mask[c] = glm::length(geom.centre(x.x, x.y, x.z) - q.position) <= reach;
                }
                const auto t0 = std::chrono::steady_clock::now();
                cast(q.position, q.intensity, 1.0, reach + h, mask, rays, dirs, f);
                source_seconds += study::seconds_since(t0);
                splatter.splat(std::span(&q, 1), w);
                for (const std::uint32_t l : w.active)
                    cast(bases.lights().position(l), w.e[l], -1.0, reach + 3.0 * h, mask, rays, dirs, f);
            }
            return f;
        };
        // The same with every kernel on its own support (the sources' and each light's, the
        // lights weighted by the whole splat): the lights' part no longer depends on the strike
        // and could be kept per light. Support: a hard ball of radius `reach`, or (tapered) the
        // last voxel of it ramped down linearly along the rays.
        auto correction_own = [&](std::span<const transport::PointSource> src, std::span<const glm::dvec3> rays,
                                  std::span<const glm::dvec3> dirs, bool tapered) {
            source_seconds = 0.0;
            NearField f{std::vector<double>(cells * dirs.size(), 0.0), std::vector<double>(cells, 0.0),
                        std::vector<double>(cells, 0.0), std::vector<double>(cells, 0.0)};
            std::vector<char> mask(cells);
            const double taper_from = tapered ? reach - h : std::numeric_limits<double>::infinity();
            auto own = [&](const glm::dvec3& p, double I, double sign) {
                for (std::size_t c = 0; c < cells; ++c) {
                    const core::Int3 x = geom.unindex(c);
                    mask[c] = tapered || glm::length(geom.centre(x.x, x.y, x.z) - p) <= reach;
                }
                cast(p, I, sign, tapered ? reach : reach + h, mask, rays, dirs, f, taper_from);
            };
            const auto t0 = std::chrono::steady_clock::now();
            for (const transport::PointSource& q : src)
                if (q.intensity != 0.0) own(q.position, q.intensity, 1.0);
            source_seconds = study::seconds_since(t0);
            lightning::LightWeights w;
            splatter.splat(src, w);
            for (const std::uint32_t l : w.active) own(bases.lights().position(l), w.e[l], -1.0);
            return f;
        };
        // The first-scattered source's multiple scattering: emission 4 pi sigma_t S1 per volume,
        // spread by the diffusion Green's function phi / (4 pi) between voxel centres (within one
        // voxel: the mean 1/r of two uniform points in a cube, 1.8823 / h), extinction the mean of
        // the two voxels'.
        auto spread = [&](const std::vector<double>& s1) {
            std::vector<double> out(cells, 0.0);
            const int R = int(std::ceil(reach / h));
            for (std::size_t c = 0; c < cells; ++c) {
                if (rho[c] <= 0.0f) continue;
                const core::Int3 x = geom.unindex(c);
                double sum = 0.0;
                for (int dk = -R; dk <= R; ++dk)
                    for (int dj = -R; dj <= R; ++dj)
                        for (int di = -R; di <= R; ++di) {
                            const int i = x.x + di, j = x.y + dj, k = x.z + dk;
                            if (i < 0 || j < 0 || k < 0 || i >= geom.dims.x || j >= geom.dims.y || k >= geom.dims.z)
                                continue;
                            const std::size_t y = geom.index(i, j, k);
                            if (s1[y] == 0.0) continue;
                            const double r = di == 0 && dj == 0 && dk == 0
                                                 ? h / 1.8823
                                                 : h * std::sqrt(double(di * di + dj * dj + dk * dk));
                            if (r > reach) continue;
                            const double sig_y = kappa * double(rho[y]);
                            const double sig = 0.5 * (sig_y + kappa * double(rho[c]));
                            sum += sig_y * s1[y] * V * diffusion_phi(r, sig, albedo, g);
                        }
                out[c] = albedo * inv4pi * sum;
            }
            return out;
        };

        for (int k = 0; k < strikes; ++k) {
            const std::uint64_t seed = std::uint64_t(k + 1);
            const study::StrikeFrame sf = study::strike_frame(ctx, storm, sc.stem, seed, truth_paths);
            const runtime::Frame& pf = sf.frame;
            const runtime::Truth& truth = sf.truth;
            const transport::SourceField tt = truth.sum();
            const std::span<const glm::dvec3> dirs = truth.single.directions;

            auto report = [&](const std::string& name, int rays, std::span<const float> b1, std::span<const float> bm,
                              const std::vector<double>* c1, const std::vector<double>* cm, double secs) {
                std::vector<float> s1(b1.begin(), b1.end()), sm(bm.begin(), bm.end()), sum(s1.size());
                for (std::size_t j = 0; j < s1.size(); ++j) {
                    if (c1) s1[j] += float((*c1)[j]);
                    if (cm) sm[j] += float((*cm)[j % cells]);
                    sum[j] = s1[j] + sm[j];
                }
                const double e1 = study::cloud_error(s1, truth.single.data, rho);
                const double em = study::cloud_error(sm, truth.multiple.data, rho);
                const double et = study::cloud_error(sum, tt.data, rho);
                rows << sc.stem << double(seed) << name << double(rays) << e1 << em << et << secs
                     << (rays ? source_seconds : 0.0);
                rows.end_row();
                const std::string key = sc.stem + ": " + name + (rays ? " (" + std::to_string(rays) + " rays)" : "");
                worst[key] = std::max(worst.value(key, 0.0), et);
                std::fprintf(
                    stderr,
                    "near-field: seed %llu %-64s single %6.3f multiple %6.3f total %6.3f (%.3f s, sources %.3f s)\n",
                    static_cast<unsigned long long>(seed), key.c_str(), e1, em, et, secs, rays ? source_seconds : 0.0);
            };
            const auto [paper1, paperm] = study::paper_parts(bases, pf, tt.data.size());
            report("paper", 0, paper1, paperm, nullptr, nullptr, 0.0);

            NearField best;
            double best_seconds = 0.0;
            for (const int n : {32, 128, 512, 2048}) {
                const std::vector<glm::dvec3> rays = core::fibonacci_sphere(n);
                auto t0 = std::chrono::steady_clock::now();
                NearField f = correction(pf.sources, rays, dirs);
                const double secs = study::seconds_since(t0);
                t0 = std::chrono::steady_clock::now();
                const std::vector<double> spread_m = spread(f.first_scattered);
                const double spread_secs = study::seconds_since(t0);
                report("near field: single", n, paper1, paperm, &f.single, nullptr, secs);
                report("near field: single + point kernel", n, paper1, paperm, &f.single, &f.multiple, secs);
                report("near field: single + transport kernel", n, paper1, paperm, &f.single, &f.transport_multiple,
                       secs);
                report("near field: single + first-scattered", n, paper1, paperm, &f.single, &spread_m,
                       secs + spread_secs);
                if (n <= 128)
                    for (const bool tapered : {false, true}) {
                        const NearField o = correction_own(pf.sources, rays, dirs, tapered);
                        const double own_secs = source_seconds;
                        t0 = std::chrono::steady_clock::now();
                        const std::vector<double> own_m = spread(o.first_scattered);
                        report(tapered ? "near field, own supports tapered: single + first-scattered"
                                       : "near field, own supports: single + first-scattered",
                               n, paper1, paperm, &o.single, &own_m, own_secs + study::seconds_since(t0));
                        if (!tapered) continue;
                        // The engine's runtime::NearField is this model: the same figures, and
                        // its time once the lights' models are kept (a strike after the first).
                        runtime::NearFieldOptions no;
                        no.rays = n;
                        const runtime::NearField engine(lm, bases.lights(), dirs, no);
                        runtime::NearFieldParts cold, warm;
                        t0 = std::chrono::steady_clock::now();
                        engine.add(pf.sources, cold);
                        const double cold_secs = study::seconds_since(t0);
                        t0 = std::chrono::steady_clock::now();
                        engine.add(pf.sources, warm);
                        const double warm_secs = study::seconds_since(t0);
                        double d2 = 0.0, r2 = 0.0;
                        for (std::size_t j = 0; j < warm.single.size(); ++j) {
                            const double ref = o.single[j] + own_m[j % cells];
                            const double mine = double(warm.single[j]) + double(warm.multiple[j]);
                            d2 += (mine - ref) * (mine - ref);
                            r2 += ref * ref;
                        }
                        const std::vector<double> warm1(warm.single.begin(), warm.single.end()),
                            warmm(warm.multiple.begin(), warm.multiple.begin() + std::ptrdiff_t(cells));
                        source_seconds = warm_secs;
                        report("engine near field", n, paper1, paperm, &warm1, &warmm, warm_secs);
                        std::fprintf(stderr,
                                     "near-field: engine against this study's model: relative L2 %.2e; %.1f ms with "
                                     "the lights' models made, %.1f ms once they are kept (%zu lights)\n",
                                     r2 > 0.0 ? std::sqrt(d2 / r2) : 0.0, 1e3 * cold_secs, 1e3 * warm_secs,
                                     engine.kept_lights());
                    }
                f.first_scattered = spread_m;
                best = std::move(f);
                best_seconds = secs + spread_secs;
            }

            // Perfect bases: the splatted virtual lights traced by the truth's Monte Carlo.
            std::vector<transport::PointSource> lights;
            for (const std::uint32_t l : pf.weights.active)
                lights.push_back({bases.lights().position(l), pf.weights.e[l]});
            runtime::TruthOptions po;
            po.paths = truth_paths / 2;
            po.seed = seed + 1000;
            const runtime::Truth traced = runtime::truth(s, density, {}, lights, po);
            report("perfect bases", 0, traced.single.data, traced.multiple.data, nullptr, nullptr, 0.0);
            report("perfect bases + single + point kernel", 2048, traced.single.data, traced.multiple.data,
                   &best.single, &best.multiple, best_seconds);
            report("perfect bases + single + transport kernel", 2048, traced.single.data, traced.multiple.data,
                   &best.single, &best.transport_multiple, best_seconds);
            report("perfect bases + single + first-scattered", 2048, traced.single.data, traced.multiple.data,
                   &best.single, &best.first_scattered, best_seconds);
        }
    }
    ctx.summary("near-field", {{"worst_total_error", worst}});
}
