// A strike's multiple scattering by the diffusion equation through the cloud's own density,
// solved per strike: whether a model that follows the density (the cloud's base and edges, where
// the near-field correction's homogeneous kernel fails) reaches the instant path's first-frame
// aim where the splat cannot.
//   strike-diffusion: the default storm's strikes 1-5 (and dusk-storm's, vdb-cloud's 1-3), each
//   at its first return stroke + 2 ms, against the truth. The strike's points' uncollided fluence
//   phi1 (transport::single_scattering's quadrature, exact) on the lighting grid refined by 1, 2
//   and 3; the first-scattered emission a sigma_t phi1 per volume; then
//     -div(D grad phi) + sigma_a phi = a sigma_t phi1,   D = 1 / (3 sigma_t (1 - a g)),
//   finite volumes on the cloud's voxels (harmonic-mean face diffusivity), Marshak's vacuum
//   condition (extrapolation distance 2D) on every face toward a clear voxel or the grid's edge,
//   solved by conjugate gradients with a Jacobi preconditioner to a relative residual of 1e-6.
//   S of orders >= 2: a / (4 pi) (phi + 3 g F . w) with F = -D grad phi (P1), or its isotropic
//   part alone; averaged onto the lighting grid. Rows: the multiple part against the truth's,
//   and the whole S with the instant path's single scattering (the bases' with the near-field
//   correction, 32 rays) and with the exact one (the truth's), beside the paper frame and the
//   instant path's first frame (bases + near-field correction).
//   Outputs: strike_diffusion.csv (one row per strike, grid and model; seconds on one thread:
//   phi1's quadrature and the solve apart).
#include "study/study.h"

#include "core/core.h"
#include "core/rng.h"
#include "runtime/near_field.h"
#include "runtime/runtime.h"
#include "runtime/strike_diffusion.h"
#include "scene/scene.h"
#include "transport/diffusion.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>

using namespace fulgur;

namespace {

struct Diffusion {
    std::vector<double> phi;       // fluence of orders >= 1 of the emission, per cell
    std::vector<glm::dvec3> flux;  // F = -D grad phi with the last pass's D
    int iterations = 0;            // conjugate-gradient iterations, summed over the limiter's passes
    double residual = 0.0;
};

bool inside(const core::GridGeometry& g, const core::Int3& o) {
    return o.x >= 0 && o.y >= 0 && o.z >= 0 && o.x < g.dims.x && o.y < g.dims.y && o.z < g.dims.z;
}

// -div(D grad phi) + sigma_a phi = q on the cells with D > 0, vacuum (Marshak: phi 0 at 2D beyond
// the face) toward the others and the grid's edge; conjugate gradients, Jacobi-preconditioned,
// from phi's values on entry.
void solve_diffusion(const transport::LightingMedium& m, const std::vector<double>& D, const std::vector<double>& q,
                     double tolerance, Diffusion& out) {
    const core::GridGeometry& g = m.density.geom;
    const std::size_t n = g.cell_count();
    const double h = g.voxel_size, V = h * h * h;
    // Face conductances toward +x, +y, +z (0 where either side is clear) and the diagonal.
    std::vector<std::array<double, 3>> G(n, {0.0, 0.0, 0.0});
    std::vector<double> diag(n, 0.0);
    for (std::size_t c = 0; c < n; ++c) {
        if (D[c] == 0.0) continue;
        const core::Int3 p = g.unindex(c);
        diag[c] += m.sigma_t(c) * (1.0 - m.optics.albedo) * V;
        for (int ax = 0; ax < 3; ++ax)
            for (const int s : {-1, 1}) {
                core::Int3 o = p;
                (ax == 0 ? o.x : ax == 1 ? o.y : o.z) += s;
                const std::size_t nb = inside(g, o) ? g.index(o.x, o.y, o.z) : 0;
                if (!inside(g, o) || D[nb] == 0.0) {
                    diag[c] += h * h * D[c] / (0.5 * h + 2.0 * D[c]);
                    continue;
                }
                const double Gf = h * 2.0 * D[c] * D[nb] / (D[c] + D[nb]);
                diag[c] += Gf;
                if (s > 0) G[c][std::size_t(ax)] = Gf;
            }
    }
    const std::array<std::size_t, 3> stride = {1, std::size_t(g.dims.x), std::size_t(g.dims.x) * g.dims.y};
    auto apply = [&](const std::vector<double>& x, std::vector<double>& y) {
        for (std::size_t c = 0; c < n; ++c) y[c] = diag[c] * x[c];
        for (std::size_t c = 0; c < n; ++c)
            for (std::size_t ax = 0; ax < 3; ++ax) {
                const double Gf = G[c][ax];
                if (Gf == 0.0) continue;
                const std::size_t nb = c + stride[ax];
                y[c] -= Gf * x[nb];
                y[nb] -= Gf * x[c];
            }
    };
    out.phi.resize(n, 0.0);
    std::vector<double> r(n), z(n), p(n), Ap(n);
    apply(out.phi, Ap);
    double bnorm = 0.0;
    for (std::size_t c = 0; c < n; ++c) {
        const double b = D[c] > 0.0 ? q[c] * V : 0.0;
        bnorm += b * b;
        r[c] = D[c] > 0.0 ? b - Ap[c] : 0.0;
    }
    bnorm = std::sqrt(bnorm);
    if (bnorm == 0.0) return;
    for (std::size_t c = 0; c < n; ++c) z[c] = diag[c] > 0.0 ? r[c] / diag[c] : 0.0;
    p = z;
    double rz = 0.0;
    for (std::size_t c = 0; c < n; ++c) rz += r[c] * z[c];
    for (int it = 1; it <= 5000; ++it) {
        apply(p, Ap);
        double pAp = 0.0;
        for (std::size_t c = 0; c < n; ++c) pAp += p[c] * Ap[c];
        const double alpha = rz / pAp;
        double rr = 0.0;
        for (std::size_t c = 0; c < n; ++c) {
            out.phi[c] += alpha * p[c];
            r[c] -= alpha * Ap[c];
            rr += r[c] * r[c];
        }
        ++out.iterations;
        out.residual = std::sqrt(rr) / bnorm;
        if (out.residual < tolerance) break;
        for (std::size_t c = 0; c < n; ++c) z[c] = diag[c] > 0.0 ? r[c] / diag[c] : 0.0;
        double rz_new = 0.0;
        for (std::size_t c = 0; c < n; ++c) rz_new += r[c] * z[c];
        const double beta = rz_new / rz;
        rz = rz_new;
        for (std::size_t c = 0; c < n; ++c) p[c] = z[c] + beta * p[c];
    }
}

// grad phi per cell by the two one-sided slopes per axis (toward a clear voxel: phi 0 at the
// extrapolated boundary 2D beyond the face).
std::vector<glm::dvec3> gradient(const core::GridGeometry& g, const std::vector<double>& D,
                                 const std::vector<double>& phi) {
    const double h = g.voxel_size;
    std::vector<glm::dvec3> out(phi.size(), glm::dvec3(0.0));
    for (std::size_t c = 0; c < phi.size(); ++c) {
        if (D[c] == 0.0) continue;
        const core::Int3 p = g.unindex(c);
        for (int ax = 0; ax < 3; ++ax) {
            double side[2], dist[2];
            for (const int s : {0, 1}) {
                core::Int3 o = p;
                (ax == 0 ? o.x : ax == 1 ? o.y : o.z) += s ? 1 : -1;
                const std::size_t nb = inside(g, o) ? g.index(o.x, o.y, o.z) : 0;
                const bool cloud = inside(g, o) && D[nb] > 0.0;
                side[s] = cloud ? phi[nb] : 0.0;
                dist[s] = cloud ? h : 0.5 * h + 2.0 * D[c];
            }
            const double up = (side[1] - phi[c]) / dist[1], down = (phi[c] - side[0]) / dist[0];
            out[c][ax] = (up * dist[0] + down * dist[1]) / (dist[0] + dist[1]);
        }
    }
    return out;
}

// Plain diffusion (D = 1 / (3 sigma_tr)) and, with `passes` > 0, Levermore-Pomraning's
// flux-limited diffusion: D = lambda(R) / sigma_tr, R = |grad phi| / (sigma_tr phi),
// lambda = (2 + R) / (6 + 3R + R^2), lagged (R from the previous pass), so |F| <= phi where the
// cloud is thin.
Diffusion diffusion(const transport::LightingMedium& m, const std::vector<double>& q, int passes) {
    const std::size_t n = m.density.geom.cell_count();
    const double tr = 1.0 - m.optics.albedo * m.optics.g;
    std::vector<double> D(n, 0.0);
    for (std::size_t c = 0; c < n; ++c)
        if (m.sigma_t(c) > 0.0) D[c] = 1.0 / (3.0 * m.sigma_t(c) * tr);
    Diffusion d;
    solve_diffusion(m, D, q, 1e-6, d);
    for (int pass = 0; pass < passes; ++pass) {
        const std::vector<glm::dvec3> grad = gradient(m.density.geom, D, d.phi);
        for (std::size_t c = 0; c < n; ++c) {
            if (D[c] == 0.0) continue;
            const double st = m.sigma_t(c) * tr;
            const double R = d.phi[c] > 0.0 ? glm::length(grad[c]) / (st * d.phi[c]) : 0.0;
            D[c] = (2.0 + R) / (6.0 + 3.0 * R + R * R) / st;
        }
        solve_diffusion(m, D, q, 1e-6, d);
    }
    d.flux = gradient(m.density.geom, D, d.phi);
    for (std::size_t c = 0; c < n; ++c) d.flux[c] *= -D[c];
    return d;
}

// a sigma_t phi1 per volume on m's cells: phi1, the uncollided fluence of the points, by the
// exact quadrature (transport::single_scattering's, one output direction).
std::vector<double> exact_emission(const scene::Scene& s, const transport::LightingMedium& m, int refine,
                                   std::span<const transport::PointSource> sources, const glm::dvec3& direction) {
    transport::SingleScatteringOptions so = solve::single_scattering_options(s);
    so.skip_block = refine;
    core::Grid3<float> phi_one;
    so.uncollided_fluence = &phi_one;
    transport::SourceField tmp(m.density.geom, std::vector<glm::dvec3>{direction});
    std::vector<double> q(m.density.geom.cell_count(), 0.0);
    for (const transport::PointSource& p : sources) {
        if (p.intensity == 0.0) continue;
        transport::single_scattering(m, p, tmp, so);
        for (std::size_t c = 0; c < q.size(); ++c) q[c] += m.optics.albedo * m.sigma_t(c) * double(phi_one.data[c]);
    }
    return q;
}

}  // namespace

FULGUR_STUDY(strike_diffusion, "strike-diffusion",
             "a strike's multiple scattering by the diffusion equation through the cloud's density, solved per "
             "strike on the lighting grid refined by 1-3, from its exact uncollided fluence, against the truth "
             "(default storm, 5 strikes; dusk-storm and vdb-cloud, 3)") {
    const std::vector<study::StrikeCase> cases = study::strike_cases(ctx.quick);
    study::Csv rows(ctx.file("strike_diffusion.csv"),
                    {"scene", "seed", "candidate", "refine", "single_error", "multiple_error", "total_error",
                     "phi1_seconds", "solve_seconds", "iterations"});
    nlohmann::json worst = nlohmann::json::object();
    for (const study::StrikeCase& sc : cases) {
        const study::StrikeScene storm = study::strike_scene(sc.file);
        const auto& [s, density, bases, media] = storm;
        const transport::LightingMedium& lm = media.lighting;
        const std::vector<float>& rho = lm.density.data;
        const std::size_t cells = rho.size();
        const std::uint64_t truth_paths = ctx.quick ? 300'000 : 1'000'000;
        for (int k = 0; k < sc.strikes; ++k) {
            const std::uint64_t seed = std::uint64_t(k + 1);
            const study::StrikeFrame sf = study::strike_frame(ctx, storm, sc.stem, seed, truth_paths);
            const runtime::Frame& pf = sf.frame;
            const runtime::Truth& truth = sf.truth;
            const transport::SourceField tt = truth.sum();
            const std::vector<glm::dvec3> dirs(truth.single.directions.begin(), truth.single.directions.end());
            const std::size_t nd = dirs.size();

            const auto [paper1, paperm] = study::paper_parts(bases, pf, tt.data.size());
            // The instant path's single scattering: the bases' with the near-field correction.
            runtime::NearFieldOptions no;
            no.rays = 32;
            const runtime::NearField nf(lm, bases.lights(), dirs, no);
            runtime::NearFieldParts corr;
            nf.add(pf.sources, corr);
            std::vector<float> instant1 = paper1, instantm = paperm;
            for (std::size_t j = 0; j < instant1.size(); ++j) {
                instant1[j] += corr.single[j];
                instantm[j] += corr.multiple[j];
            }
            auto report = [&](const std::string& name, int refine, std::span<const float> s1, std::span<const float> sm,
                              double phi1_secs, double solve_secs, int iterations) {
                std::vector<float> sum(s1.size());
                for (std::size_t j = 0; j < sum.size(); ++j) sum[j] = s1[j] + sm[j];
                const double e1 = study::cloud_error(s1, truth.single.data, rho);
                const double em = study::cloud_error(sm, truth.multiple.data, rho);
                const double et = study::cloud_error(sum, tt.data, rho);
                rows << sc.stem << double(seed) << name << double(refine) << e1 << em << et << phi1_secs << solve_secs
                     << double(iterations);
                rows.end_row();
                const std::string key = sc.stem + ": " + name + (refine ? " refine " + std::to_string(refine) : "");
                worst[key] = std::max(worst.value(key, 0.0), et);
                std::fprintf(stderr,
                             "strike-diffusion: seed %llu %-58s single %6.3f multiple %6.3f total %6.3f (phi1 %.2f s, "
                             "solve %.3f s, %d iterations)\n",
                             static_cast<unsigned long long>(seed), key.c_str(), e1, em, et, phi1_secs, solve_secs,
                             iterations);
            };
            report("paper", 0, paper1, paperm, 0.0, 0.0, 0);
            // What an isotropic multiple part can reach at best: the truth's multiple part
            // replaced by its mean over the directions, and by its least-squares fit a + b . w
            // (what a P1 model could reach), each with the exact single scattering.
            {
                std::vector<float> iso(truth.multiple.data.size()), p1(truth.multiple.data.size());
                for (std::size_t c = 0; c < cells; ++c) {
                    // Normal equations of [1, wx, wy, wz] over the directions.
                    double A[4][4] = {}, b[4] = {};
                    for (std::size_t m = 0; m < nd; ++m) {
                        const double f[4] = {1.0, dirs[m].x, dirs[m].y, dirs[m].z};
                        const double y = truth.multiple.data[m * cells + c];
                        for (int i = 0; i < 4; ++i) {
                            b[i] += f[i] * y;
                            for (int j = 0; j < 4; ++j) A[i][j] += f[i] * f[j];
                        }
                    }
                    for (std::size_t m = 0; m < nd; ++m) iso[m * cells + c] = float(b[0] / A[0][0]);
                    // Gaussian elimination (A is symmetric positive definite for 26 directions).
                    for (int i = 0; i < 4; ++i)
                        for (int r = i + 1; r < 4; ++r) {
                            const double f = A[r][i] / A[i][i];
                            for (int j = i; j < 4; ++j) A[r][j] -= f * A[i][j];
                            b[r] -= f * b[i];
                        }
                    double x[4];
                    for (int i = 3; i >= 0; --i) {
                        double v = b[i];
                        for (int j = i + 1; j < 4; ++j) v -= A[i][j] * x[j];
                        x[i] = v / A[i][i];
                    }
                    for (std::size_t m = 0; m < nd; ++m)
                        p1[m * cells + c] = float(x[0] + x[1] * dirs[m].x + x[2] * dirs[m].y + x[3] * dirs[m].z);
                }
                report("truth's multiple, isotropic part + exact single", 0, truth.single.data, iso, 0.0, 0.0, 0);
                report("truth's multiple, P1 fit + exact single", 0, truth.single.data, p1, 0.0, 0.0, 0);
            }
            report("instant first frame", 0, instant1, instantm, 0.0, 0.0, 0);
            // The engine's first frame: runtime::StrikeDiffusion (the instant preset's
            // near_field_multiple "diffusion") with its single part by the same cast, and with
            // NearField's single part (32 rays) instead; the time each takes (NearField on every
            // thread, the lights' models kept; the diffusion on one).
            {
                runtime::NearFieldOptions so;
                so.rays = 32;
                so.multiple = false;
                const runtime::NearField single_only(lm, bases.lights(), dirs, so);
                runtime::NearFieldParts nf_parts;
                single_only.add(pf.sources, nf_parts);  // makes the lights' models
                nf_parts = {};
                auto t0 = std::chrono::steady_clock::now();
                single_only.add(pf.sources, nf_parts);
                const double nf_secs = study::seconds_since(t0);
                auto engine_row = [&](const std::string& label, const runtime::StrikeDiffusionOptions& sdo,
                                      const transport::LightingMedium* full) {
                    const runtime::StrikeDiffusion sd(lm, bases, dirs, sdo, full);
                    runtime::NearFieldParts parts = sdo.single ? runtime::NearFieldParts{} : nf_parts;
                    const auto ts = std::chrono::steady_clock::now();
                    sd.add(pf.sources, parts);
                    const double secs = study::seconds_since(ts);
                    std::vector<float> e1 = paper1, em = paperm;
                    for (std::size_t j = 0; j < e1.size(); ++j) {
                        e1[j] += parts.single[j];
                        em[j] += parts.multiple[j];
                    }
                    report(label, 1, e1, em, sdo.single ? 0.0 : nf_secs, secs, sd.last_iterations());
                    return secs;
                };
                runtime::StrikeDiffusionOptions cast_single;
                const double sd_secs = engine_row("engine: cast single + strike diffusion", cast_single, nullptr);
                runtime::StrikeDiffusionOptions near_single;
                near_single.single = false;
                engine_row("engine: near-field single + strike diffusion", near_single, nullptr);
                for (const int rays : {64, 128, 512}) {
                    runtime::StrikeDiffusionOptions more;
                    more.rays = rays;
                    engine_row("engine: cast single + strike diffusion, " + std::to_string(rays) + " rays", more,
                               nullptr);
                }
                // The single scattering cast through the full-resolution density (the truth's
                // medium, S averaged over each lighting cell by volume as the truth tallies it),
                // its first-scattered light fed to the diffusion, or the lighting grid's cast's.
                const transport::LightingMedium full{density, s.medium};
                for (const int rays : {32, 64, 128, 256, 512})
                    for (const bool fe : {true, false}) {
                        runtime::StrikeDiffusionOptions sdo;
                        sdo.fine_rays = rays;
                        sdo.fine_emission = fe;
                        engine_row("engine: full-density single, " + std::to_string(rays) + " rays" +
                                       (fe ? "" : ", the lighting grid's emission"),
                                   sdo, &full);
                    }
                // The solve's knobs: limiter passes and the conjugate gradients' tolerance.
                for (const auto& [passes, tol] : {std::pair{4, 1e-4}, std::pair{4, 1e-3}, std::pair{2, 1e-4},
                                                  std::pair{2, 1e-3}, std::pair{1, 1e-3}}) {
                    runtime::StrikeDiffusionOptions sdo;
                    sdo.single = false;
                    sdo.diffusion.limiter_passes = passes;
                    sdo.diffusion.tolerance = tol;
                    char label[96];
                    std::snprintf(label, sizeof label, "engine: strike diffusion, %d passes, tolerance %g", passes,
                                  tol);
                    engine_row(label, sdo, nullptr);
                }
                // The engine's solver against this study's (whole grid, plain loops) on the same
                // emission.
                std::vector<double> q;
                transport::add_first_scattered_emission(lm, pf.sources, 32, 1, q);
                transport::DiffusionOptions eo;  // the study's solver's settings
                eo.tolerance = 1e-6;
                const Diffusion naive = diffusion(lm, q, eo.limiter_passes);
                const transport::DiffusionField fast = transport::solve_diffusion(lm, q, eo);
                double d2 = 0.0, r2 = 0.0;
                for (std::size_t c = 0; c < cells; ++c) {
                    d2 += (double(fast.fluence[c]) - naive.phi[c]) * (double(fast.fluence[c]) - naive.phi[c]);
                    r2 += naive.phi[c] * naive.phi[c];
                }
                std::fprintf(stderr,
                             "strike-diffusion: engine solver against this study's: relative L2 %.2e; near field %.1f "
                             "ms, cast + diffusion %.1f ms (the check's solve: %d iterations, %s)\n",
                             std::sqrt(d2 / r2), 1e3 * nf_secs, 1e3 * sd_secs, fast.iterations,
                             fast.converged ? "converged" : "NOT converged");
            }
            // The instant path's single scattering with 128 rays (the knob's next step).
            std::vector<float> instant1_128 = paper1;
            {
                runtime::NearFieldOptions o128;
                o128.rays = 128;
                runtime::NearFieldParts c128;
                runtime::NearField(lm, bases.lights(), dirs, o128).add(pf.sources, c128);
                for (std::size_t j = 0; j < instant1_128.size(); ++j) instant1_128[j] += c128.single[j];
            }

            for (const int refine : {1, 2}) {
                if (s.lighting_downsample % refine != 0) continue;
                const solve::Media fm = solve::make_media(s, density, refine, false);
                const transport::LightingMedium& tm = fm.transport;
                const core::GridGeometry& tg = tm.density.geom;
                const std::size_t fc = tg.cell_count();
                const double a = tm.optics.albedo, inv4pi = 0.25 / std::numbers::pi;
                // The first-scattered emission a sigma_t phi1 of the strike's points, summed:
                // phi1 by the exact quadrature (0 rays) or by `rays` rays cast from each point.
                for (const int rays : {0, 32, 128}) {
                    auto t0 = std::chrono::steady_clock::now();
                    std::vector<double> q;
                    if (rays)
                        transport::add_first_scattered_emission(tm, pf.sources, rays, 1, q);
                    else
                        q = exact_emission(s, tm, refine, pf.sources, dirs[0]);
                    const double phi1_secs = study::seconds_since(t0);
                    for (const int passes : {0, 4}) {
                        if (rays && !passes) continue;
                        t0 = std::chrono::steady_clock::now();
                        const Diffusion d = diffusion(tm, q, passes);
                        const double solve_secs = study::seconds_since(t0);
                        // S of orders >= 2: isotropic, or the phase function applied to a radiance
                        // lobe of mean cosine |F| / phi along +F or -F (HG lobes compose as HG with
                        // the product of their g): a phi p_HG(w . F^, g |F| / phi), never negative.
                        for (const int lobe : {0, 1, -1}) {
                            if ((lobe && !passes) || (rays && lobe != 1)) continue;
                            transport::SourceField fine(tg, dirs);
                            for (std::size_t m = 0; m < nd; ++m)
                                for (std::size_t c = 0; c < fc; ++c) {
                                    double v = a * inv4pi * d.phi[c];
                                    const double f = glm::length(d.flux[c]);
                                    if (lobe && f > 0.0 && d.phi[c] > 0.0) {
                                        const double kf = std::min(f / d.phi[c], 0.99);
                                        v = a * d.phi[c] *
                                            transport::hg_phase(lobe * glm::dot(dirs[m], d.flux[c]) / f,
                                                                tm.optics.g * kf);
                                    }
                                    fine.data[m * fc + c] = float(v);
                                }
                            const transport::SourceField coarse =
                                refine > 1 ? transport::block_average(fine, refine) : fine;
                            const std::string name = std::string(passes ? "flux-limited diffusion" : "diffusion") +
                                                     (lobe == 1    ? ", lobe along F"
                                                      : lobe == -1 ? ", lobe against F"
                                                                   : "") +
                                                     (rays ? ", phi1 by " + std::to_string(rays) + " rays" : "");
                            report(name + " + instant single", refine, instant1, coarse.data, phi1_secs, solve_secs,
                                   d.iterations);
                            if (lobe == 1)
                                report(name + " + instant single (128 rays)", refine, instant1_128, coarse.data,
                                       phi1_secs, solve_secs, d.iterations);
                            report(name + " + exact single", refine, truth.single.data, coarse.data, phi1_secs,
                                   solve_secs, d.iterations);
                        }
                    }
                }
            }
        }
    }
    ctx.summary("strike-diffusion", {{"worst_total_error", worst}});
}
