// Flux-limited diffusion of a first-scattered emission (diffusion.h).
#include "transport/diffusion.h"

#include "core/core.h"
#include "core/rng.h"
#include "transport/detail/traversal.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>

namespace fulgur::transport {

namespace {

// The cloud's cells as a compact list: their grid index and, per face (-x, +x, -y, +y, -z, +z),
// the neighbour's position in the list (-1: a clear voxel or the grid's edge).
struct Cells {
    std::vector<std::uint32_t> grid;
    std::vector<std::array<std::int32_t, 6>> nb;
    std::vector<double> sigma_t;
};

Cells cloud_cells(const LightingMedium& m) {
    const core::GridGeometry& g = m.density.geom;
    const std::size_t n = g.cell_count();
    FULGUR_ASSERT(n < std::size_t(std::numeric_limits<std::int32_t>::max()), "solve_diffusion: grid too large");
    std::vector<std::int32_t> at(n, -1);
    Cells c;
    for (std::size_t i = 0; i < n; ++i) {
        const double st = m.sigma_t(i);
        if (!(st > 0.0) || !std::isfinite(st)) continue;
        at[i] = std::int32_t(c.grid.size());
        c.grid.push_back(std::uint32_t(i));
        c.sigma_t.push_back(st);
    }
    c.nb.resize(c.grid.size());
    for (std::size_t a = 0; a < c.grid.size(); ++a) {
        const core::Int3 p = g.unindex(c.grid[a]);
        for (int f = 0; f < 6; ++f) {
            core::Int3 o = p;
            const int s = (f & 1) ? 1 : -1;
            (f < 2 ? o.x : f < 4 ? o.y : o.z) += s;
            const bool inside = o.x >= 0 && o.y >= 0 && o.z >= 0 && o.x < g.dims.x && o.y < g.dims.y && o.z < g.dims.z;
            c.nb[a][std::size_t(f)] = inside ? at[g.index(o.x, o.y, o.z)] : -1;
        }
    }
    return c;
}

// grad phi per cloud cell: per axis the two one-sided slopes, each weighted by the other side's
// distance (toward a clear face: phi 0 at the extrapolated boundary 2D beyond it).
void gradient(const Cells& c, const std::vector<double>& D, const std::vector<double>& phi, double h,
              std::vector<glm::dvec3>& out) {
    out.assign(c.grid.size(), glm::dvec3(0.0));
    for (std::size_t a = 0; a < c.grid.size(); ++a)
        for (int ax = 0; ax < 3; ++ax) {
            double side[2], dist[2];
            for (int s = 0; s < 2; ++s) {
                const std::int32_t b = c.nb[a][std::size_t(2 * ax + s)];
                side[s] = b >= 0 ? phi[std::size_t(b)] : 0.0;
                dist[s] = b >= 0 ? h : 0.5 * h + 2.0 * D[a];
            }
            const double up = (side[1] - phi[a]) / dist[1], down = (phi[a] - side[0]) / dist[0];
            out[a][ax] = (up * dist[0] + down * dist[1]) / (dist[0] + dist[1]);
        }
}

// One solve of -div(D grad phi) + sigma_a phi = q (b = q V per cell) by Jacobi-preconditioned
// conjugate gradients from phi's values on entry. Returns the iterations; sets `converged`.
int conjugate_gradients(const Cells& c, const std::vector<double>& D, const std::vector<double>& b, double sigma_a_per,
                        double h, const DiffusionOptions& o, std::vector<double>& phi, bool& converged) {
    const std::size_t n = c.grid.size();
    const double V = h * h * h;
    // Conductances of the +x, +y, +z faces (0 toward a clear voxel) and the diagonal.
    std::vector<std::array<double, 3>> G(n, {0.0, 0.0, 0.0});
    std::vector<double> diag(n, 0.0);
    for (std::size_t a = 0; a < n; ++a) {
        diag[a] += c.sigma_t[a] * sigma_a_per * V;
        for (int f = 0; f < 6; ++f) {
            const std::int32_t nb = c.nb[a][std::size_t(f)];
            if (nb < 0) {
                diag[a] += h * h * D[a] / (0.5 * h + 2.0 * D[a]);
                continue;
            }
            const double Gf = 2.0 * h * D[a] * D[std::size_t(nb)] / (D[a] + D[std::size_t(nb)]);
            diag[a] += Gf;
            if (f & 1) G[a][std::size_t(f / 2)] = Gf;
        }
    }
    auto apply = [&](const std::vector<double>& x, std::vector<double>& y) {
        for (std::size_t a = 0; a < n; ++a) y[a] = diag[a] * x[a];
        for (std::size_t a = 0; a < n; ++a)
            for (std::size_t ax = 0; ax < 3; ++ax) {
                const std::int32_t nb = c.nb[a][2 * ax + 1];
                if (nb < 0) continue;
                const double Gf = G[a][ax];
                y[a] -= Gf * x[std::size_t(nb)];
                y[std::size_t(nb)] -= Gf * x[a];
            }
    };
    std::vector<double> r(n), z(n), p(n), Ap(n);
    apply(phi, Ap);
    double bnorm = 0.0;
    for (std::size_t a = 0; a < n; ++a) {
        bnorm += b[a] * b[a];
        r[a] = b[a] - Ap[a];
    }
    bnorm = std::sqrt(bnorm);
    if (!(bnorm > 0.0)) {
        std::fill(phi.begin(), phi.end(), 0.0);
        return 0;
    }
    for (std::size_t a = 0; a < n; ++a) z[a] = r[a] / diag[a];
    p = z;
    double rz = 0.0, rr = 0.0;
    for (std::size_t a = 0; a < n; ++a) {
        rz += r[a] * z[a];
        rr += r[a] * r[a];
    }
    if (std::sqrt(rr) <= o.tolerance * bnorm) return 0;
    for (int it = 1; it <= o.max_iterations; ++it) {
        apply(p, Ap);
        double pAp = 0.0;
        for (std::size_t a = 0; a < n; ++a) pAp += p[a] * Ap[a];
        if (!(pAp > 0.0)) {
            converged = false;
            return it;
        }
        const double alpha = rz / pAp;
        rr = 0.0;
        for (std::size_t a = 0; a < n; ++a) {
            phi[a] += alpha * p[a];
            r[a] -= alpha * Ap[a];
            rr += r[a] * r[a];
        }
        if (std::sqrt(rr) <= o.tolerance * bnorm) return it;
        double rz_new = 0.0;
        for (std::size_t a = 0; a < n; ++a) {
            z[a] = r[a] / diag[a];
            rz_new += r[a] * z[a];
        }
        const double beta = rz_new / rz;
        rz = rz_new;
        for (std::size_t a = 0; a < n; ++a) p[a] = z[a] + beta * p[a];
    }
    converged = false;
    return o.max_iterations;
}

}  // namespace

DiffusionField solve_diffusion(const LightingMedium& m, std::span<const double> emission,
                               const DiffusionOptions& options) {
    const core::GridGeometry& g = m.density.geom;
    FULGUR_ASSERT(emission.size() == g.cell_count(), "solve_diffusion: emission is not one value per cell");
    FULGUR_ASSERT(options.limiter_passes >= 0 && options.limiter_passes <= 64,
                  "solve_diffusion: limiter_passes must be in [0, 64]");
    FULGUR_ASSERT(options.tolerance > 0.0 && options.max_iterations >= 1,
                  "solve_diffusion: bad tolerance or iterations");
    DiffusionField out;
    out.geom = g;
    out.fluence.assign(g.cell_count(), 0.0f);
    out.flux.assign(g.cell_count(), glm::vec3(0.0f));
    const Cells c = cloud_cells(m);
    const std::size_t n = c.grid.size();
    if (n == 0) return out;
    const double h = g.voxel_size, V = h * h * h;
    const double albedo = std::clamp(m.optics.albedo, 0.0, 1.0);
    const double tr = 1.0 - albedo * std::clamp(m.optics.g, -kMaxAbsG, kMaxAbsG);
    std::vector<double> b(n), D(n), phi(n, 0.0);
    for (std::size_t a = 0; a < n; ++a) {
        const double q = emission[c.grid[a]];
        b[a] = std::isfinite(q) && q > 0.0 ? q * V : 0.0;
        D[a] = 1.0 / (3.0 * c.sigma_t[a] * tr);
    }
    std::vector<glm::dvec3> grad;
    for (int pass = 0; pass <= options.limiter_passes; ++pass) {
        if (pass > 0) {
            gradient(c, D, phi, h, grad);
            for (std::size_t a = 0; a < n; ++a) {
                const double st = c.sigma_t[a] * tr;
                const double R = phi[a] > 0.0 ? glm::length(grad[a]) / (st * phi[a]) : 0.0;
                D[a] = (2.0 + R) / (6.0 + 3.0 * R + R * R) / st;
            }
        }
        out.iterations += conjugate_gradients(c, D, b, 1.0 - albedo, h, options, phi, out.converged);
    }
    gradient(c, D, phi, h, grad);
    for (std::size_t a = 0; a < n; ++a) {
        out.fluence[c.grid[a]] = float(std::max(phi[a], 0.0));
        out.flux[c.grid[a]] = glm::vec3(-D[a] * grad[a]);
    }
    return out;
}

void add_diffusion_source(const LightingMedium& m, const DiffusionField& field, std::span<const glm::dvec3> directions,
                          double w, std::span<float> out) {
    const std::size_t cells = field.geom.cell_count(), nd = directions.size();
    FULGUR_ASSERT(field.fluence.size() == cells && field.flux.size() == cells, "add_diffusion_source: bad field");
    FULGUR_ASSERT(out.size() == nd * cells, "add_diffusion_source: out is not [directions][cells]");
    const double a = std::clamp(m.optics.albedo, 0.0, 1.0), g = std::clamp(m.optics.g, -kMaxAbsG, kMaxAbsG);
    const double inv4pi = 0.25 / std::numbers::pi;
    for (std::size_t c = 0; c < cells; ++c) {
        const double phi = field.fluence[c];
        if (!(phi > 0.0)) continue;
        const glm::dvec3 F(field.flux[c]);
        const double f = glm::length(F);
        if (!(f > 0.0)) {
            for (std::size_t k = 0; k < nd; ++k) out[k * cells + c] += float(w * a * phi * inv4pi);
            continue;
        }
        // The lobe's mean cosine |F| / phi is at most 1 by the limiter; 0.99 keeps the HG finite.
        const double gk = g * std::min(f / phi, 0.99);
        for (std::size_t k = 0; k < nd; ++k)
            out[k * cells + c] += float(w * a * phi * hg_phase(glm::dot(directions[k], F) / f, gk));
    }
}

namespace {

// A point's Fibonacci sphere of rays turned by a rotation hashed from (seed, point): the
// pattern's pole to a uniform direction w, then a uniform turn about it.
struct TurnedSphere {
    glm::dvec3 t, b, w;
    double turn = 0.0;
    TurnedSphere(std::uint64_t seed, std::size_t point) {
        core::Rng rng(core::hash_seed(seed, point));
        const double az0 = 2.0 * std::numbers::pi * rng.uniform(), z0 = 2.0 * rng.uniform() - 1.0;
        const double s0 = std::sqrt(std::max(0.0, 1.0 - z0 * z0));
        w = glm::dvec3(s0 * std::cos(az0), s0 * std::sin(az0), z0);
        t = glm::normalize(glm::cross(w, std::fabs(w.x) > 0.5 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0)));
        b = glm::cross(w, t);
        turn = 2.0 * std::numbers::pi * rng.uniform();
    }
    glm::dvec3 direction(int r, int rays) const noexcept {
        const glm::dvec3 f = core::fibonacci_direction(r, rays, turn);
        return t * f.x + b * f.y + w * f.z;
    }
};

bool finite_source(const PointSource& p) noexcept {
    return std::isfinite(p.position.x) && std::isfinite(p.position.y) && std::isfinite(p.position.z) &&
           std::isfinite(p.intensity) && p.intensity != 0.0;
}

// The cast of add_first_scattered_emission and add_point_scattering: the emission always, the
// single scattering in `directions` when `single` is given.
void cast_points(const LightingMedium& m, std::span<const PointSource> sources, int rays, std::uint64_t seed,
                 std::span<const glm::dvec3> directions, std::vector<double>& emission, std::vector<double>* single) {
    FULGUR_ASSERT(rays >= 1 && rays <= 65536, "point source cast: rays must be in [1, 65536]");
    const core::GridGeometry& g = m.density.geom;
    const std::size_t cells = g.cell_count(), nd = directions.size();
    if (emission.empty()) emission.assign(cells, 0.0);
    FULGUR_ASSERT(emission.size() == cells, "point source cast: emission is not one value per cell");
    if (single && single->empty()) single->assign(nd * cells, 0.0);
    FULGUR_ASSERT(!single || single->size() == nd * cells, "point source cast: single is not [directions][cells]");
    const double g_hg = std::clamp(m.optics.g, -kMaxAbsG, kMaxAbsG);
    std::vector<double> phase(single ? nd : 0);
    const double h = g.voxel_size, V = h * h * h, dr = 0.25 * h, d_omega = 4.0 * std::numbers::pi / rays;
    const double albedo = std::clamp(m.optics.albedo, 0.0, 1.0);
    const double dims[3] = {double(g.dims.x), double(g.dims.y), double(g.dims.z)};
    for (std::size_t n = 0; n < sources.size(); ++n) {
        const PointSource& p = sources[n];
        if (!finite_source(p)) continue;
        const TurnedSphere sphere(seed, n);
        const glm::dvec3 v0 = g.to_voxel(p.position);
        const double scale = albedo * p.intensity * dr * d_omega / V;
        for (int r = 0; r < rays; ++r) {
            const glm::dvec3 u = sphere.direction(r, rays);
            for (std::size_t k = 0; k < phase.size(); ++k) phase[k] = hg_phase(glm::dot(u, directions[k]), g_hg);
            // The ray's stretch inside the grid's box (slabs, in voxels).
            double t_in = 0.0, t_out = std::numeric_limits<double>::infinity();
            for (int ax = 0; ax < 3; ++ax) {
                const double d = u[ax] / h;
                if (std::fabs(d) < 1e-300) {
                    if (v0[ax] < 0.0 || v0[ax] > dims[ax]) t_out = -1.0;
                    continue;
                }
                const double ta = -v0[ax] / d, tb = (dims[ax] - v0[ax]) / d;
                t_in = std::max(t_in, std::min(ta, tb));
                t_out = std::min(t_out, std::max(ta, tb));
            }
            if (!(t_out > t_in)) continue;
            // Counted steps (a source far away cannot make r0 + dr == r0 loop for ever): at most
            // the box's diagonal in quarter voxels.
            const double span = std::min((t_out - t_in) / dr, 4.0 * (dims[0] + dims[1] + dims[2]) + 8.0);
            const long steps = long(std::ceil(span));
            double tau = 0.0;
            for (long s = 0; s < steps; ++s) {
                const glm::dvec3 v = v0 + u * ((t_in + (double(s) + 0.5) * dr) / h);
                const int i = int(std::floor(v.x)), j = int(std::floor(v.y)), k = int(std::floor(v.z));
                if (i < 0 || j < 0 || k < 0 || i >= g.dims.x || j >= g.dims.y || k >= g.dims.z) continue;
                const std::size_t c = g.index(i, j, k);
                const double st = m.sigma_t(c);
                if (!(st > 0.0)) continue;
                const double e = scale * std::exp(-(tau + 0.5 * st * dr));
                emission[c] += e * st;
                if (single)
                    for (std::size_t d = 0; d < nd; ++d) (*single)[d * cells + c] += e * phase[d];
                tau += st * dr;
                if (tau > 30.0) break;
            }
        }
    }
}

}  // namespace

void add_first_scattered_emission(const LightingMedium& m, std::span<const PointSource> sources, int rays,
                                  std::uint64_t seed, std::vector<double>& emission) {
    cast_points(m, sources, rays, seed, {}, emission, nullptr);
}

void add_point_scattering(const LightingMedium& m, std::span<const PointSource> sources, int rays, std::uint64_t seed,
                          std::span<const glm::dvec3> directions, std::vector<double>& emission,
                          std::vector<double>& single) {
    cast_points(m, sources, rays, seed, directions, emission, &single);
}

void add_point_scattering_fine(const LightingMedium& fine, const core::GridGeometry& onto,
                               std::span<const PointSource> sources, int rays, std::uint64_t seed,
                               std::span<const glm::dvec3> directions, std::vector<double>& emission,
                               std::vector<double>& single, const core::Grid3<float>* onto_density) {
    FULGUR_ASSERT(rays >= 1 && rays <= 65536, "point source cast: rays must be in [1, 65536]");
    const core::GridGeometry& g = fine.density.geom;
    const std::size_t cells = onto.cell_count(), nd = directions.size();
    if (emission.empty()) emission.assign(cells, 0.0);
    if (single.empty()) single.assign(nd * cells, 0.0);
    FULGUR_ASSERT(emission.size() == cells && single.size() == nd * cells,
                  "point source cast: emission and single are not [cells] and [directions][cells] of `onto`");
    FULGUR_ASSERT(!onto_density || onto_density->geom == onto, "point source cast: onto_density is not on `onto`");
    const double g_hg = std::clamp(fine.optics.g, -kMaxAbsG, kMaxAbsG);
    const double albedo = std::clamp(fine.optics.albedo, 0.0, 1.0);
    const double V = onto.voxel_size * onto.voxel_size * onto.voxel_size, d_omega = 4.0 * std::numbers::pi / rays;
    const glm::dvec3 centre = g.origin + 0.5 * g.extent();
    // `onto`'s cell of a fine voxel: by integer division when the grids nest (the lighting grid
    // over the cloud's: same origin, a whole number of fine voxels per cell), else by the
    // position of the ray's midpoint in the voxel.
    const double ratio = onto.voxel_size / g.voxel_size;
    const int nest = int(std::lround(ratio));
    const bool nested = nest >= 1 && std::fabs(ratio - nest) < 1e-9 * ratio &&
                        glm::length(onto.origin - g.origin) < 1e-9 * onto.voxel_size;
    // With `onto`'s density on nesting grids a ray walks `onto`'s cells and descends into the
    // fine voxels only where the cell holds cloud: clear air is crossed a cell at a time.
    const bool two_level = nested && onto_density != nullptr;
    // S accumulated cell-major ([cell][direction]: one flush writes one contiguous run), moved
    // into `single`'s [direction][cell] layout at the end.
    std::vector<double> acc(cells * nd, 0.0), phase(nd);
    for (std::size_t n = 0; n < sources.size(); ++n) {
        const PointSource& p = sources[n];
        if (!finite_source(p)) continue;
        const TurnedSphere sphere(seed, n);
        const double scale = albedo * p.intensity * d_omega / V;
        // Far enough to leave the box from anywhere the source may be (finite: checked above).
        const double reach = glm::length(g.extent()) + glm::length(p.position - centre);
        for (int r = 0; r < rays; ++r) {
            const glm::dvec3 u = sphere.direction(r, rays);
            for (std::size_t k = 0; k < nd; ++k) phase[k] = scale * hg_phase(glm::dot(u, directions[k]), g_hg);
            // Sums of exp(-tau) ds (phi) and sigma_t exp(-tau) ds (emission) over the stretch
            // the ray spends inside one cell of `onto`, added once it leaves the cell.
            std::ptrdiff_t cell = -1;
            double phi = 0.0, em = 0.0;
            auto enter = [&](std::ptrdiff_t c) {
                if (c == cell) return;
                if (cell >= 0 && phi != 0.0) {
                    emission[std::size_t(cell)] += scale * em;
                    double* to = acc.data() + std::size_t(cell) * nd;
                    for (std::size_t k = 0; k < nd; ++k) to[k] += phi * phase[k];
                }
                cell = c;
                phi = em = 0.0;
            };
            double tau = 0.0, T = 1.0;  // optical depth and transmittance from the point
            // One fine voxel's stretch of length len and extinction st: the exact integral of
            // exp(-tau) over it. False once the light left is negligible (optical depth 30).
            auto cross = [&](double st, double len) {
                const double x = st * len;
                if (x > 1e-8) {
                    const double absorbed = -std::expm1(-x);
                    phi += T * absorbed / st;
                    em += T * absorbed;
                    T -= T * absorbed;
                } else {
                    phi += T * len;
                    em += T * x;
                }
                tau += x;
                return tau <= 30.0;
            };
            // The fine voxels of o + t u, t in [t0, t1]; `c` >= 0: all in that cell of `onto`.
            auto walk_fine = [&](double t0, double t1, std::ptrdiff_t c) {
                detail::DdaWalker walk;
                if (!walk.start(g, p.position, u, t0, t1)) return true;
                do {
                    const double a = walk.t, b = walk.t_next(), len = b - a;
                    if (!(len > 0.0)) continue;
                    if (c < 0) {
                        int i, j, k;
                        if (nested) {
                            i = walk.i / nest;
                            j = walk.j / nest;
                            k = walk.k / nest;
                        } else {
                            const glm::dvec3 v = onto.to_voxel(p.position + u * (0.5 * (a + b)));
                            i = int(std::floor(v.x));
                            j = int(std::floor(v.y));
                            k = int(std::floor(v.z));
                        }
                        const bool inside =
                            i >= 0 && j >= 0 && k >= 0 && i < onto.dims.x && j < onto.dims.y && k < onto.dims.z;
                        enter(inside ? std::ptrdiff_t(onto.index(i, j, k)) : -1);
                    }
                    if (!cross(fine.sigma_t(std::size_t(walk.cell)), len)) return false;
                } while (walk.advance());
                return true;
            };
            if (!two_level) {
                walk_fine(0.0, reach, -1);
            } else {
                // `onto`'s cells over the stretch inside the fine grid's box.
                double t0 = 0.0, t1 = reach;
                if (core::clip_ray_to_box(p.position, u, g.origin, g.upper(), t0, t1)) {
                    detail::DdaWalker walk;
                    if (walk.start(onto, p.position, u, t0, t1)) do {
                            const double a = walk.t, b = walk.t_next();
                            if (!(b > a)) continue;
                            enter(walk.cell);
                            if (onto_density->data[std::size_t(walk.cell)] > 0.0f) {
                                if (!walk_fine(a, b, walk.cell)) break;
                            } else if (!cross(0.0, b - a)) {
                                break;
                            }
                        } while (walk.advance());
                }
            }
            enter(-1);
        }
    }
    for (std::size_t c = 0; c < cells; ++c)
        for (std::size_t k = 0; k < nd; ++k) single[k * cells + c] += acc[c * nd + k];
}

}  // namespace fulgur::transport
