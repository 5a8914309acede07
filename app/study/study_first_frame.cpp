// What a strike's very first frame can be lit with, before any per-strike work has run.
//   first-frame: the default storm's strikes 1-5 at their first return stroke + 2 ms, each
//   candidate estimate against the truth of that frame, single and multiple scattering apart:
//   the paper frame (the splat), exact single scattering of the frame's point sources on the
//   lighting grid, the bases' multiple scattering with virtual-light weights fitted to the
//   strike's first-scattered field (non-negative least squares) instead of the splat's, and
//   the splat with perfect bases (the splatted virtual lights traced by the truth's Monte
//   Carlo) at the bake's spacing and 2x and 4x denser.
//   Outputs: first_frame.csv (one row per strike and candidate).
#include "study/study.h"

#include "bake/bake.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <glm/geometric.hpp>

using namespace fulgur;

namespace {

// Non-negative least squares min |A c - b|^2, c >= 0, by cyclic coordinate descent on the
// normal equations (G = A^T A, r = A^T b); n is small (the lights near one bolt).
std::vector<double> nnls(const std::vector<double>& G, const std::vector<double>& r, std::size_t n, int sweeps) {
    std::vector<double> c(n, 0.0), g(n, 0.0);  // g = G c
    for (int s = 0; s < sweeps; ++s)
        for (std::size_t i = 0; i < n; ++i) {
            const double gii = G[i * n + i];
            if (gii <= 0.0) continue;
            const double next = std::max(0.0, c[i] + (r[i] - g[i]) / gii);
            const double d = next - c[i];
            if (d == 0.0) continue;
            c[i] = next;
            for (std::size_t j = 0; j < n; ++j) g[j] += G[j * n + i] * d;
        }
    return c;
}

}  // namespace

FULGUR_STUDY(first_frame, "first-frame",
             "a strike's first frame before any per-strike work: the splat, exact single scattering of the point "
             "sources on the lighting grid, the bases' multiple scattering with fitted virtual-light weights, and "
             "the splat with perfect bases at the bake's spacing and 2x and 4x denser, against the truth (default "
             "storm, 5 strikes)") {
    const study::StrikeScene storm = study::strike_scene("storm.json");
    const auto& [s, density, bases, media] = storm;
    const std::vector<float>& rho = media.lighting.density.data;
    const std::size_t cells = rho.size();
    const std::uint64_t truth_paths = ctx.quick ? 300'000 : 2'000'000;
    const int strikes = ctx.quick ? 2 : 5;

    // Isotropic copy of the medium: the scalar first-scattered field (albedo/(4 pi) x voxel
    // average of I T / r^2), what the multiple scattering of a source depends on.
    transport::LightingMedium iso = media.transport;
    iso.optics.g = 0.0;
    const std::vector<glm::dvec3> one = {glm::dvec3(0, 0, 1)};
    transport::SingleScatteringOptions sso = solve::single_scattering_options(s);
    auto scalar_s1 = [&](std::span<const transport::PointSource> src) {
        std::vector<double> out(cells, 0.0);
        for (const transport::PointSource& q : src) {
            const transport::SourceField f = transport::single_scattering(iso, q, one, sso);
            for (std::size_t c = 0; c < cells; ++c) out[c] += double(f.data[c]);
        }
        return out;
    };

    const basis::VirtualLightGrid& vl = bases.lights();
    const lightning::Splatter splatter(vl);
    study::Csv rows(ctx.file("first_frame.csv"),
                    {"seed", "candidate", "single_error", "multiple_error", "total_error", "seconds"});
    for (int k = 0; k < strikes; ++k) {
        const std::uint64_t seed = std::uint64_t(k + 1);
        const study::StrikeFrame sf = study::strike_frame(ctx, storm, "storm", seed, truth_paths);
        const runtime::Frame& pf = sf.frame;
        const runtime::Truth& truth = sf.truth;
        const transport::SourceField tt = truth.sum();

        runtime::Reconstructor rec(bases);
        auto part = [&](const lightning::LightWeights& w, bool single) {
            runtime::ReconstructOptions o;
            o.components = {single, !single};
            runtime::RadianceField r;
            runtime::StageTimes st;
            if (!rec.reconstruct(w, {}, o, r, st)) return std::vector<float>(tt.data.size(), 0.0f);
            return study::flat(r);
        };
        auto report = [&](const std::string& name, const std::vector<float>& s1, const std::vector<float>& sm,
                          double secs) {
            std::vector<float> sum(s1.size());
            for (std::size_t j = 0; j < sum.size(); ++j) sum[j] = s1[j] + sm[j];
            const double e1 = study::cloud_error(s1, truth.single.data, rho);
            const double em = study::cloud_error(sm, truth.multiple.data, rho);
            const double et = study::cloud_error(sum, tt.data, rho);
            rows << double(seed) << name << e1 << em << et << secs;
            rows.end_row();
            std::fprintf(stderr, "first-frame: seed %llu %-28s single %6.3f multiple %6.3f total %6.3f (%.4f s)\n",
                         static_cast<unsigned long long>(seed), name.c_str(), e1, em, et, secs);
        };
        const std::vector<float> paper1 = part(pf.weights, true), paperm = part(pf.weights, false);
        report("paper", paper1, paperm, 0.0);

        auto t0 = std::chrono::steady_clock::now();
        const transport::SourceField d1 = runtime::direct_solve(s, media, pf.sources, {true, false});
        const double direct_s = study::seconds_since(t0);
        report("direct single + paper multiple", d1.data, paperm, direct_s);
        const transport::SourceField dm = runtime::direct_solve(s, media, pf.sources, {false, true});
        report("direct single + direct multiple", d1.data, dm.data, direct_s);

        // Fitted weights: the lights within two spacings of a source.
        t0 = std::chrono::steady_clock::now();
        const double reach = 2.0 * 1500.0;
        std::vector<std::uint32_t> near;
        for (std::uint32_t l = 0; l < vl.count(); ++l) {
            const glm::dvec3 p = vl.position(l);
            for (const transport::PointSource& q : pf.sources)
                if (glm::length(q.position - p) <= reach) {
                    near.push_back(l);
                    break;
                }
        }
        std::vector<std::vector<double>> A;
        for (const std::uint32_t l : near) {
            const transport::PointSource q{vl.position(l), 1.0};
            A.push_back(scalar_s1(std::span(&q, 1)));
        }
        const double basis_s = study::seconds_since(t0);
        t0 = std::chrono::steady_clock::now();
        const std::vector<double> b = scalar_s1(pf.sources);
        const double target_s = study::seconds_since(t0);
        const std::size_t n = near.size();
        std::vector<double> G(n * n, 0.0), r(n, 0.0);
        for (std::size_t a = 0; a < n; ++a) {
            for (std::size_t c = 0; c < cells; ++c)
                if (rho[c] > 0.0f) r[a] += A[a][c] * b[c];
            for (std::size_t bb = 0; bb <= a; ++bb) {
                double v = 0.0;
                for (std::size_t c = 0; c < cells; ++c)
                    if (rho[c] > 0.0f) v += A[a][c] * A[bb][c];
                G[a * n + bb] = G[bb * n + a] = v;
            }
        }
        const std::vector<double> coef = nnls(G, r, n, 400);
        const double fit_s = study::seconds_since(t0);
        lightning::LightWeights w;
        splatter.reset(w);
        for (std::size_t a = 0; a < n; ++a)
            if (coef[a] > 0.0) {
                w.e[near[a]] = coef[a];
                w.active.push_back(near[a]);
                w.touched[near[a]] = 1;
                w.total += coef[a];
            }
        std::vector<double> fitted(cells, 0.0);
        for (std::size_t a = 0; a < n; ++a)
            for (std::size_t c = 0; c < cells; ++c) fitted[c] += coef[a] * A[a][c];
        std::vector<float> fa(fitted.begin(), fitted.end());
        std::vector<float> ba(b.begin(), b.end());
        std::fprintf(stderr,
                     "first-frame: seed %llu: %zu lights near, %zu fitted, scalar S1 fit error %.3f, splat total %.4g "
                     "fitted total %.4g; times basis %.2f s target %.3f s fit %.3f s\n",
                     static_cast<unsigned long long>(seed), n, w.active.size(), study::cloud_error(fa, ba, rho),
                     pf.weights.total, w.total, basis_s, target_s, fit_s);
        const std::vector<float> fitm = part(w, false), fit1 = part(w, true);
        report("fitted single + fitted multiple", fit1, fitm, fit_s);
        report("direct single + fitted multiple", d1.data, fitm, direct_s + fit_s);

        // What the splat would give with perfect bases: the virtual lights at the splat's
        // weights traced by the truth's own Monte Carlo (no lattice, no compression), on the
        // bake's grid and with nodes inserted between the bake's on every axis (2x, 4x
        // denser: how dense perfect bases would have to be under the splat); then the frame's
        // point sources traced the same way (the channel cut into points, no splat).
        runtime::TruthOptions po;
        po.paths = truth_paths / 2;
        po.seed = seed + 1000;
        for (const int split : {1, 2, 4}) {
            basis::VirtualLightGrid dense;
            auto refine_axis = [&](const std::vector<double>& a) {
                std::vector<double> out;
                for (std::size_t q = 0; q + 1 < a.size(); ++q)
                    for (int d = 0; d < split; ++d) out.push_back(a[q] + (a[q + 1] - a[q]) * d / split);
                out.push_back(a.back());
                return out;
            };
            dense.x = refine_axis(vl.x);
            dense.y = refine_axis(vl.y);
            dense.z = refine_axis(vl.z);
            const lightning::Splatter ds(dense);
            lightning::LightWeights dw;
            ds.splat(pf.sources, dw);
            std::vector<transport::PointSource> dpts;
            for (const std::uint32_t l : dw.active) dpts.push_back({dense.position(l), dw.e[l]});
            t0 = std::chrono::steady_clock::now();
            const runtime::Truth dt = runtime::truth(s, density, {}, dpts, po);
            const std::string lights = split == 1 ? "" : ", lights " + std::to_string(split) + "x denser";
            report(split == 1 ? std::string("splat traced (exact bases)") : "splat traced" + lights, dt.single.data,
                   dt.multiple.data, study::seconds_since(t0));
            report("direct single + splat traced multiple" + lights, d1.data, dt.multiple.data, direct_s);
        }
        t0 = std::chrono::steady_clock::now();
        const runtime::Truth ps = runtime::truth(s, density, {}, pf.sources, po);
        report("point sources traced", ps.single.data, ps.multiple.data, study::seconds_since(t0));
    }
}
