// Whether smoothing a strike's early Monte Carlo estimate brings it closer to the truth.
//   denoise: the default storm's strikes 1-5 at their first return stroke + 2 ms, the instant
//   preset's two tracers (order 1 by expected-value emissions, orders >= 2 by whole paths; each
//   group weighted by the frame's glow, as a frame shows them) run as two independent halves
//   at the path counts of ~50, ~100 and ~300 ms of the instant worker; the estimate (the
//   halves' mean) with 0-2 passes of a binomial [1 2 1] / 4 filter along each axis of the
//   lighting grid on its single and 0-3 on its multiple part, against the truth (relative L2
//   over the cloud), and the same filter chosen without the truth: each half filtered against
//   the other half raw (cross-validation; its square is the filtered estimate's error plus the
//   other half's noise).
//   Outputs: denoise.csv (one row per strike, path count and filter).
#include "study/study.h"

#include "bake/bake.h"
#include "core/core.h"
#include "runtime/runtime.h"
#include "runtime/strike_solver.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <algorithm>
#include <cstdio>

using namespace fulgur;

namespace {

// `passes` of [1 2 1] / 4 along x, y and z in turn, per direction, clamped at the grid's edges.
std::vector<float> binomial(const std::vector<float>& in, const core::GridGeometry& g, std::size_t ndir, int passes) {
    std::vector<float> a = in, b(in.size());
    const core::Int3 n = g.dims;
    const std::size_t cells = g.cell_count();
    for (int p = 0; p < passes; ++p)
        for (int axis = 0; axis < 3; ++axis) {
            const int len = axis == 0 ? n.x : axis == 1 ? n.y : n.z;
            const std::size_t stride = axis == 0 ? 1 : axis == 1 ? std::size_t(n.x) : std::size_t(n.x) * n.y;
            for (std::size_t m = 0; m < ndir; ++m)
                for (std::size_t c = 0; c < cells; ++c) {
                    const core::Int3 ijk = g.unindex(c);
                    const int at = axis == 0 ? ijk.x : axis == 1 ? ijk.y : ijk.z;
                    const float* v = a.data() + m * cells + c;
                    const float lo = at > 0 ? *(v - stride) : *v, hi = at + 1 < len ? *(v + stride) : *v;
                    b[m * cells + c] = 0.25f * lo + 0.5f * *v + 0.25f * hi;
                }
            std::swap(a, b);
        }
    return a;
}

// Squared L2 distance over the cloud's voxels (rho > 0), every direction.
double dist2(std::span<const float> x, std::span<const float> y, const std::vector<float>& rho) {
    const std::size_t cells = rho.size();
    double s = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i)
        if (rho[i % cells] > 0.0f) s += (double(x[i]) - double(y[i])) * (double(x[i]) - double(y[i]));
    return s;
}

std::vector<float> plus(const std::vector<float>& a, const std::vector<float>& b) {
    std::vector<float> s(a.size());
    for (std::size_t i = 0; i < s.size(); ++i) s[i] = a[i] + b[i];
    return s;
}

}  // namespace

FULGUR_STUDY(denoise, "denoise",
             "a strike's early Monte Carlo estimate smoothed on the lighting grid (binomial passes, chosen by "
             "cross-validation between its halves) against the truth (default storm, 5 strikes)") {
    const study::StrikeScene storm = study::strike_scene("storm.json");
    const auto& [s, density, bases, media] = storm;
    const std::vector<float>& rho = media.lighting.density.data;
    const core::GridGeometry& geom = media.lighting.density.geom;
    const transport::LightingMedium fine{density, s.medium};
    const transport::MonteCarloMedium tracing(fine, geom);
    const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
    const std::uint64_t truth_paths = ctx.quick ? 300'000 : 2'000'000;
    const int strikes = ctx.quick ? 2 : 5;
    // Order-1 and orders >= 2 paths the instant worker has traced by ~50, ~100 and ~300 ms on
    // this machine (docs/presets.md, fulgur-study latency).
    const std::vector<std::pair<std::uint64_t, std::uint64_t>> budgets = {{3000, 10000}, {8000, 30000}, {20000, 80000}};

    study::Csv rows(ctx.file("denoise.csv"), {"seed", "single_paths", "multiple_paths", "single_passes",
                                              "multiple_passes", "error_vs_truth", "cross_validated"});
    nlohmann::json out = nlohmann::json::array();
    for (int k = 0; k < strikes; ++k) {
        const std::uint64_t seed = std::uint64_t(k + 1);
        const study::StrikeFrame sf = study::strike_frame(ctx, storm, "storm", seed, truth_paths);
        lightning::Storm& probe_storm = sf.probe->storm();
        const lightning::Strike& strike = probe_storm.strike(sf.strike);
        const std::vector<float> tt = sf.truth.sum().data;
        const double tn2 = dist2(tt, std::vector<float>(tt.size(), 0.0f), rho);
        const lightning::FlashState st =
            lightning::flash_state(strike.profile, probe_storm.params().timing, sf.time - strike.time);
        const std::vector<transport::LineSource> lines = runtime::strike_line_sources(probe_storm.bolt(sf.strike));
        for (const auto& [n1, nm] : budgets) {
            // Two independent halves of each part, the groups at the frame's glow.
            std::array<std::vector<float>, 2> h1, hm;
            for (int h = 0; h < 2; ++h) {
                std::array<transport::MonteCarloOptions, 2> o = runtime::instant_tracer_options();
                o[0].seed = core::hash_seed(seed, 10 + h);
                o[1].seed = core::hash_seed(seed, 20 + h);
                transport::ProgressiveMonteCarlo ps(tracing, {}, lines, dirs, o[0]), pm(tracing, {}, lines, dirs, o[1]);
                ps.advance(n1 / 2);
                pm.advance(nm / 2);
                const transport::MonteCarloResult rs = ps.result(), rm = pm.result();
                h1[h].resize(rs.single.data.size());
                hm[h].resize(rm.multiple.data.size());
                for (std::size_t i = 0; i < h1[h].size(); ++i) {
                    h1[h][i] = float(st.main_glow * rs.groups[0].single.data[i] +
                                     st.branch_glow * rs.groups[1].single.data[i]);
                    hm[h][i] = float(st.main_glow * rm.groups[0].multiple.data[i] +
                                     st.branch_glow * rm.groups[1].multiple.data[i]);
                }
            }
            std::vector<float> e1(h1[0].size()), em(hm[0].size());
            for (std::size_t i = 0; i < e1.size(); ++i) {
                e1[i] = 0.5f * (h1[0][i] + h1[1][i]);
                em[i] = 0.5f * (hm[0][i] + hm[1][i]);
            }
            // Each field filtered once per pass count (filtered[p] = p passes).
            const auto passes = [&](const std::vector<float>& f, int most) {
                std::vector<std::vector<float>> filtered{f};
                for (int p = 1; p <= most; ++p) filtered.push_back(binomial(filtered.back(), geom, dirs.size(), 1));
                return filtered;
            };
            const auto e1f = passes(e1, 2), emf = passes(em, 3);
            const std::array<std::vector<std::vector<float>>, 2> h1f = {passes(h1[0], 2), passes(h1[1], 2)},
                                                                 hmf = {passes(hm[0], 3), passes(hm[1], 3)};
            const std::array<std::vector<float>, 2> raw_half = {plus(h1[0], hm[0]), plus(h1[1], hm[1])};
            double best_cv = 1e300, chosen = 0.0, raw = 0.0;
            for (int p1 = 0; p1 <= 2; ++p1)
                for (int p2 = 0; p2 <= 3; ++p2) {
                    const double err = std::sqrt(dist2(plus(e1f[p1], emf[p2]), tt, rho) / tn2);
                    double cv2 = 0.0;
                    for (int h = 0; h < 2; ++h) cv2 += 0.5 * dist2(plus(h1f[h][p1], hmf[h][p2]), raw_half[1 - h], rho);
                    const double cv = std::sqrt(cv2 / tn2);
                    rows << double(seed) << double(n1) << double(nm) << double(p1) << double(p2) << err << cv;
                    rows.end_row();
                    if (p1 == 0 && p2 == 0) raw = err;
                    if (cv < best_cv) {
                        best_cv = cv;
                        chosen = err;
                    }
                    std::fprintf(stderr,
                                 "denoise: seed %llu, %llu + %llu paths, passes %d (single) %d (multiple): error %.4f, "
                                 "cross-validated %.4f\n",
                                 static_cast<unsigned long long>(seed), static_cast<unsigned long long>(n1),
                                 static_cast<unsigned long long>(nm), p1, p2, err, cv);
                }
            out.push_back(
                {{"seed", seed}, {"single_paths", n1}, {"multiple_paths", nm}, {"raw", raw}, {"chosen", chosen}});
        }
    }
    ctx.summary("denoise", {{"rows", out}, {"truth_paths", truth_paths}});
}
