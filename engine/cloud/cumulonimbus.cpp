// The cumulonimbus generator: parameter validation, seed-ellipsoid layout, seed field, and
// the pipeline automaton -> space-time average -> density. See docs/cloud.md.
#include "cloud/detail/automaton.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace fulgur::cloud {

namespace {

constexpr std::uint64_t kLayoutTag = 0x6c61796f7574ULL;   // "layout"
constexpr std::uint64_t kAutomatonTag = 0x6175746f6dULL;  // "autom"

std::string generator_field(const char* name) { return std::string("cloud.generator.") + name; }

std::string metres(double v) { return core::format_number(v) + " m"; }

[[noreturn]] void fail(const char* name, const std::string& what) { throw core::Error(generator_field(name), what); }

void require_finite(const char* name, double v) {
    if (!std::isfinite(v)) fail(name, "must be a finite number, got " + std::to_string(v));
}

void require_probability(const char* name, double v) {
    require_finite(name, v);
    if (v < 0.0 || v > 1.0) fail(name, "is a probability and must be in [0, 1], got " + std::to_string(v));
}

// Groups of ellipsoids, so a shape that does not fit names the parameter behind it.
enum class Part { Tower, Flank, Anvil, Overshoot };

struct Placed {
    detail::Ellipsoid e;
    Part part;
};

// Vertical profile of a tower: where it stands, how high it goes, how wide it is.
struct TowerSpec {
    double x0 = 0.0, y0 = 0.0;  // foot of the axis
    double lean = 0.0;          // +x displacement of the summit relative to the foot
    double base = 0.0;          // flat base height
    double summit = 0.0;        // highest visible point
    double radius = 0.0;        // radius at the base
    int turrets = 0;
    double clip = 0.0;      // nothing above this height
    bool dome = true;       // round the summit off (no anvil above)
    double softness = 0.5;  // ellipsoid edge softness
    double flare = 0.0;     // relative widening of the top quarter (into an anvil)
};

// The automaton's cloud fraction is roughly proportional to the seed weight; the visible
// edge (weight ~0.1) of an ellipsoid with this softness lies at this normalized distance.
// The layout uses it to put visible edges where the parameters say.
double visible_fraction(double softness) { return 1.0 - 0.17 * softness; }

void add_tower(const TowerSpec& t, Part part, core::Rng& rng, std::vector<Placed>& out) {
    const double height = t.summit - t.base;
    auto axis_x = [&](double z) {
        const double s = std::clamp((z - t.base) / height, 0.0, 1.0);
        return t.x0 + t.lean * std::pow(s, 1.5);  // shear grows with height
    };
    // The tower narrows by 20% from its base to its summit region; under an anvil its top
    // quarter flares out into the anvil.
    auto radius_at = [&](double z) {
        const double s = std::clamp((z - t.base) / height, 0.0, 1.0);
        const double f = std::clamp((s - 0.75) / 0.25, 0.0, 1.0);
        return t.radius * (1.0 - 0.2 * s) * (1.0 + t.flare * f * f);
    };
    // Core column: overlapping ellipsoids on the axis, the lowest centred on the base so
    // that the flat cut there is a broad disc.
    const double summit_r = radius_at(t.summit);
    const double core_top = t.dome ? t.summit - visible_fraction(t.softness) * 0.75 * summit_r : t.summit;
    const int n_core = std::max(2, int(std::ceil((core_top - t.base) / (0.45 * t.radius))) + 1);
    for (int n = 0; n < n_core; ++n) {
        const double z = t.base + (core_top - t.base) * double(n) / double(n_core - 1);
        const double r = radius_at(z);
        detail::Ellipsoid e;
        const double rh = (n == 0 ? 1.25 : 1.0) * r * (0.95 + 0.1 * rng.uniform());
        e.centre = {axis_x(z), t.y0, z};
        e.radii = {rh, rh, (n == 0 ? 0.5 : 0.75) * r};
        e.strength = 1.0;
        e.softness = t.softness;
        e.z_max = t.clip;
        out.push_back({e, part});
    }
    // Turrets: convective cells bulging from the flanks, stratified in height, spread in
    // azimuth by the golden angle (even coverage) with jitter.
    constexpr double kGolden = 2.399963229728653;  // radians
    const double phase = 2.0 * std::numbers::pi * rng.uniform();
    for (int n = 0; n < t.turrets; ++n) {
        const double s = (double(n) + rng.uniform()) / double(t.turrets);
        const double z = t.base + s * (core_top - t.base);
        const double r_tower = radius_at(z);
        const double r = r_tower * (0.32 + 0.22 * rng.uniform());
        const double phi = phase + kGolden * double(n) + 0.5 * (rng.uniform() - 0.5);
        // Dome turrets sit closer to the axis so they cap the summit.
        const double top_fraction = t.dome ? std::clamp((s - 0.8) / 0.2, 0.0, 1.0) : 0.0;
        const double rho = (r_tower - 0.35 * r) * (1.0 - 0.6 * top_fraction);
        detail::Ellipsoid e;
        e.centre = {axis_x(z) + rho * std::cos(phi), t.y0 + rho * std::sin(phi), z + top_fraction * 0.5 * r};
        e.radii = {r, r, r * (0.85 + 0.25 * rng.uniform())};
        e.strength = 0.85 + 0.15 * rng.uniform();
        e.softness = t.softness;
        e.z_max = t.clip;
        out.push_back({e, part});
        // Cauliflower: smaller bubbles on the turret's outer, upper surface (a second scale
        // of lumps).
        for (int c = 0; c < 2; ++c) {
            const double a = phi + 1.6 * (rng.uniform() - 0.5);
            const double up = std::min(0.95, 0.15 + 0.6 * rng.uniform() + 0.5 * top_fraction);
            const double side = std::sqrt(1.0 - up * up);
            const glm::dvec3 dir(side * std::cos(a), side * std::sin(a), up);
            detail::Ellipsoid b = e;
            const double rb = r * (0.38 + 0.17 * rng.uniform());
            b.centre = e.centre + dir * (0.8 * r);
            b.radii = {rb, rb, rb * (0.85 + 0.2 * rng.uniform())};
            out.push_back({b, part});
        }
    }
}

std::vector<Placed> layout(const CumulonimbusParams& p) {
    core::Rng rng(core::hash_seed(p.seed, kLayoutTag));
    std::vector<Placed> out;
    const double anvil_top = p.anvil ? p.top_height - p.overshoot : p.top_height;

    TowerSpec main;
    main.base = p.base_height;
    main.summit = anvil_top;
    main.radius = p.tower_radius;
    main.lean = p.shear;
    main.turrets = p.cells;
    main.clip = p.top_height;
    main.dome = !p.anvil;
    main.softness = p.edge_softness;
    main.flare = p.anvil ? 0.5 : 0.0;
    if (p.anvil) {
        main.clip = anvil_top;
        // The column runs into the anvil; its top is the anvil's flat top.
        main.summit = anvil_top;
    }
    add_tower(main, Part::Tower, rng, out);

    // Flanking line: towers upwind and to the side (towards -x, -y), each lower and
    // narrower than the one before, sharing the flat base.
    const double tower_height = anvil_top - p.base_height;
    for (int f = 0; f < p.flanking_towers; ++f) {
        TowerSpec t;
        const double dist = p.tower_radius * (1.15 + 0.65 * double(f)) * (0.95 + 0.1 * rng.uniform());
        const double phi = std::numbers::pi * (1.2 + 0.06 * double(f)) + 0.15 * (rng.uniform() - 0.5);
        t.radius = p.tower_radius * std::max(0.25, 0.6 - 0.1 * double(f));
        t.x0 = dist * std::cos(phi);
        t.y0 = dist * std::sin(phi);
        t.base = p.base_height;
        t.summit = p.base_height + tower_height * std::max(0.2, 0.62 - 0.13 * double(f)) * (0.9 + 0.2 * rng.uniform());
        t.lean = p.shear * (t.summit - t.base) / std::max(tower_height, 1.0) * 0.5;
        t.turrets = std::max(2, p.cells / 4);
        t.clip = p.top_height;
        t.dome = true;
        t.softness = p.edge_softness;
        add_tower(t, Part::Flank, rng, out);
    }

    if (p.anvil) {
        const double tx = p.shear;              // the tower's top
        const double cx = tx + p.anvil_offset;  // the anvil's centre
        const double ra = p.anvil_radius;
        const double reach = ra + p.anvil_offset;  // farthest anvil edge from the tower
        // A plate of flat ellipsoids, clipped at the flat top (the tropopause): thickest
        // over the tower, its underside rising towards the edge; weaker and softer towards
        // the edge, where the anvil turns thin and diffuse.
        const int n_anvil = 48;
        for (int n = 0; n < n_anvil; ++n) {
            double x, y, rx;
            if (n == 0) {
                // Where the tower meets the anvil.
                x = tx;
                y = 0.0;
                rx = std::max(0.3 * ra, 1.2 * p.tower_radius);
            } else {
                rx = ra * (0.2 + 0.15 * rng.uniform());
                const double spread = std::max(0.0, ra - 1.15 * rx);
                const double rho = spread * std::sqrt((double(n) - 0.5 + 0.5 * rng.uniform()) / double(n_anvil - 1));
                const double phi = 2.0 * std::numbers::pi * rng.uniform();
                x = cx + rho * std::cos(phi);
                y = rho * std::sin(phi);
            }
            const double from_tower = std::min(1.0, std::hypot(x - tx, y) / reach);
            const double edge = std::min(1.0, std::hypot(x - cx, y) / ra);
            const double thick =
                p.anvil_thickness * (1.0 - 0.7 * from_tower * from_tower) * (0.85 + 0.3 * rng.uniform());
            detail::Ellipsoid e;
            e.radii = {rx * 1.15, rx * (0.75 + 0.2 * rng.uniform()), 0.8 * thick};
            e.centre = {x, y, anvil_top - 0.35 * thick};
            e.strength = 1.0 - 0.6 * std::pow(edge, 1.5);
            e.softness = p.edge_softness + (1.0 - p.edge_softness) * edge;
            e.z_max = anvil_top;
            out.push_back({e, Part::Anvil});
        }
        if (p.overshoot > 0.0) {
            detail::Ellipsoid e;
            const double r = 0.6 * p.tower_radius;
            e.centre = {tx, 0.0, anvil_top - 0.3 * p.overshoot};
            e.radii = {r, r, 1.3 * p.overshoot / visible_fraction(p.edge_softness)};
            e.strength = 1.0;
            e.softness = p.edge_softness;
            e.z_max = p.top_height;
            out.push_back({e, Part::Overshoot});
        }
    }
    return out;
}

// Throws if a part's ellipsoids leave the grid (with a margin for the smoothing kernel),
// naming the parameter that sizes that part.
void check_fits(const CumulonimbusParams& p, const std::vector<Placed>& placed) {
    const core::GridGeometry g = cumulonimbus_geometry(p);
    const double margin = double(p.smoothing_radius + 1) * p.voxel_size;
    const glm::dvec3 lo = g.origin + margin, hi = g.upper() - margin;
    for (const Placed& pl : placed) {
        const detail::Ellipsoid& e = pl.e;
        const glm::dvec3 a = e.centre - e.radii, b = e.centre + e.radii;
        const bool fits = a.x >= lo.x && a.y >= lo.y && b.x <= hi.x && b.y <= hi.y;
        if (fits) continue;
        const std::string grid = std::to_string(p.grid.x) + "x" + std::to_string(p.grid.y) + " voxels of " +
                                 metres(p.voxel_size) + ", i.e. x, y in [" + metres(lo.x) + ", " + metres(hi.x) +
                                 "] after a " + metres(margin) + " margin for smoothing";
        switch (pl.part) {
            case Part::Tower:
            case Part::Overshoot:
                fail("tower_radius", "the tower (radius " + metres(p.tower_radius) + ", shear " + metres(p.shear) +
                                         ") does not fit in the grid (" + grid + "); reduce it or enlarge the grid");
            case Part::Flank:
                fail("flanking_towers", std::to_string(p.flanking_towers) +
                                            " flanking towers beside a tower of radius " + metres(p.tower_radius) +
                                            " do not fit in the grid (" + grid + "); use fewer or enlarge the grid");
            case Part::Anvil:
                fail("anvil_radius", "the anvil (radius " + metres(p.anvil_radius) + ", centred " +
                                         metres(p.shear + p.anvil_offset) +
                                         " downwind of the tower's foot) does not fit in the grid (" + grid +
                                         "); reduce anvil_radius, anvil_offset or shear, or enlarge the grid");
        }
    }
}

}  // namespace

void validate_cumulonimbus(const CumulonimbusParams& p) {
    // Grid.
    constexpr int kMinDim = 8;  // below this there is no room for a base, a body and a top
    if (p.grid.x < kMinDim || p.grid.y < kMinDim || p.grid.z < kMinDim || p.grid.x > 4096 || p.grid.y > 4096 ||
        p.grid.z > 4096)
        fail("grid", "each dimension must be in [8, 4096], got " + std::to_string(p.grid.x) + "x" +
                         std::to_string(p.grid.y) + "x" + std::to_string(p.grid.z));
    require_finite("voxel_size", p.voxel_size);
    if (!(p.voxel_size > 0.0)) fail("voxel_size", "must be a positive length in metres, got " + metres(p.voxel_size));
    core::validate_geometry(cumulonimbus_geometry(p), generator_field("grid"));

    // Plain ranges.
    for (auto [name, v] : {std::pair{"base_height", p.base_height},
                           {"top_height", p.top_height},
                           {"tower_radius", p.tower_radius},
                           {"shear", p.shear},
                           {"anvil_radius", p.anvil_radius},
                           {"anvil_thickness", p.anvil_thickness},
                           {"anvil_offset", p.anvil_offset},
                           {"overshoot", p.overshoot},
                           {"edge_softness", p.edge_softness},
                           {"density_gain", p.density_gain}})
        require_finite(name, v);
    if (!(p.edge_softness > 0.0) || p.edge_softness > 1.0)
        fail("edge_softness", "must be in (0, 1], got " + std::to_string(p.edge_softness));
    require_probability("p_ext", p.p_ext);
    require_probability("p_hum", p.p_hum);
    require_probability("p_act", p.p_act);
    if (!(p.p_hum > 0.0)) fail("p_hum", "must be > 0: without vapour supply nothing ever condenses");
    if (!(p.p_act > 0.0)) fail("p_act", "must be > 0: without activation supply nothing ever condenses");
    if (p.cells < 0 || p.cells > 1000) fail("cells", "must be in [0, 1000], got " + std::to_string(p.cells));
    if (p.flanking_towers < 0 || p.flanking_towers > 8)
        fail("flanking_towers", "must be in [0, 8], got " + std::to_string(p.flanking_towers));
    if (p.steps < 1 || p.steps > 1000) fail("steps", "must be in [1, 1000], got " + std::to_string(p.steps));
    if (p.average_steps < 1 || p.average_steps > 255)
        fail("average_steps", "must be in [1, 255], got " + std::to_string(p.average_steps));
    if (p.average_steps > p.steps)
        fail("average_steps", "the averaging window (" + std::to_string(p.average_steps) +
                                  " steps) must not be longer than the run (steps = " + std::to_string(p.steps) + ")");
    if (p.smoothing_radius < 0 || p.smoothing_radius > 16)
        fail("smoothing_radius", "must be in [0, 16] voxels, got " + std::to_string(p.smoothing_radius));
    if (!(p.density_gain > 0.0) || p.density_gain > 100.0)
        fail("density_gain", "must be in (0, 100], got " + std::to_string(p.density_gain));

    // Vertical consistency.
    const double h = p.voxel_size;
    const double grid_top = double(p.grid.z) * h;
    const double margin = double(p.smoothing_radius + 1) * h;
    if (p.base_height < 0.0) fail("base_height", "must be >= 0 (above the ground), got " + metres(p.base_height));
    if (!(p.top_height > p.base_height))
        fail("top_height", "must be above base_height (" + metres(p.base_height) + "), got " + metres(p.top_height));
    if (p.top_height - p.base_height < 6.0 * h)
        fail("top_height", "the cloud (" + metres(p.base_height) + " to " + metres(p.top_height) +
                               ") must be at least 6 voxels (" + metres(6.0 * h) +
                               ") tall to have a base, a body and a top");
    if (p.top_height > grid_top - margin)
        fail("top_height", metres(p.top_height) + " does not fit in the grid: its top is at " + metres(grid_top) +
                               " (" + std::to_string(p.grid.z) + " voxels of " + metres(h) +
                               ") and the smoothing needs " + metres(margin) + " above the cloud");

    // Horizontal sizes.
    if (p.tower_radius < 2.0 * h)
        fail("tower_radius",
             "must be at least 2 voxels (" + metres(2.0 * h) + ") to be resolved, got " + metres(p.tower_radius));
    if (std::fabs(p.shear) > 2.0 * p.tower_radius)
        fail("shear", "|shear| must be at most twice tower_radius (" + metres(2.0 * p.tower_radius) +
                          ") or the tower breaks apart, got " + metres(p.shear));

    if (p.anvil) {
        if (!(p.anvil_radius > p.tower_radius))
            fail("anvil_radius", "must be larger than tower_radius (" + metres(p.tower_radius) +
                                     "): an anvil is wider than its tower; got " + metres(p.anvil_radius));
        if (p.anvil_thickness < 2.0 * h)
            fail("anvil_thickness",
                 "must be at least 2 voxels (" + metres(2.0 * h) + "), got " + metres(p.anvil_thickness));
        if (p.overshoot < 0.0) fail("overshoot", "must be >= 0, got " + metres(p.overshoot));
        if (p.overshoot > p.anvil_thickness)
            fail("overshoot",
                 "must be at most anvil_thickness (" + metres(p.anvil_thickness) + "), got " + metres(p.overshoot));
        const double anvil_bottom = p.top_height - p.overshoot - p.anvil_thickness;
        if (anvil_bottom - p.base_height < 0.3 * (p.top_height - p.base_height))
            fail("anvil_thickness", "anvil (" + metres(p.anvil_thickness) + ") plus overshoot (" + metres(p.overshoot) +
                                        ") leave less than 30% of the cloud's height (" + metres(p.base_height) +
                                        " to " + metres(p.top_height) + ") for the tower below the anvil");
        if (p.anvil_offset < 0.0 || p.anvil_offset > p.anvil_radius - p.tower_radius)
            fail("anvil_offset", "must be in [0, anvil_radius - tower_radius] = [0, " +
                                     metres(p.anvil_radius - p.tower_radius) +
                                     "] so the anvil stays over the tower, got " + metres(p.anvil_offset));
    }
    check_fits(p, layout(p));
}

core::GridGeometry cumulonimbus_geometry(const CumulonimbusParams& p) {
    core::GridGeometry g;
    g.dims = p.grid;
    g.voxel_size = p.voxel_size;
    g.origin = glm::dvec3(-0.5 * p.grid.x * p.voxel_size, -0.5 * p.grid.y * p.voxel_size, 0.0);
    return g;
}

namespace detail {

std::vector<Ellipsoid> cumulonimbus_layout(const CumulonimbusParams& p) {
    std::vector<Ellipsoid> e;
    for (const Placed& pl : layout(p)) e.push_back(pl.e);
    return e;
}

double ellipsoid_weight(const Ellipsoid& e, double d2) noexcept {
    if (!(d2 < 1.0)) return 0.0;
    const double t = std::clamp((std::sqrt(d2) - (1.0 - e.softness)) / e.softness, 0.0, 1.0);
    const double u = 1.0 - t * t;
    return e.strength * u * u;
}

std::vector<std::uint8_t> seed_field(const core::GridGeometry& g, std::span<const Ellipsoid> ellipsoids,
                                     double floor_z) {
    const int nx = g.dims.x, ny = g.dims.y, nz = g.dims.z;
    std::vector<std::uint8_t> out(g.cell_count(), 0);
    core::parallel_for(0, nz, [&](std::int64_t kk) {
        const int k = int(kk);
        const double z = g.centre(0, 0, k).z;
        if (z < floor_z) return;
        std::vector<float> w(std::size_t(nx) * std::size_t(ny), 0.0f);
        for (const Ellipsoid& e : ellipsoids) {
            if (z > e.z_max) continue;
            const double dz = (z - e.centre.z) / e.radii.z;
            const double dz2 = dz * dz;
            if (dz2 >= 1.0) continue;
            // Horizontal bounding box of the slice through the ellipsoid.
            const glm::dvec3 lo = g.to_voxel(e.centre - e.radii), hi = g.to_voxel(e.centre + e.radii);
            const int i0 = std::max(0, int(std::floor(lo.x))), i1 = std::min(nx - 1, int(std::ceil(hi.x)));
            const int j0 = std::max(0, int(std::floor(lo.y))), j1 = std::min(ny - 1, int(std::ceil(hi.y)));
            for (int j = j0; j <= j1; ++j) {
                const double dy = (g.centre(0, j, k).y - e.centre.y) / e.radii.y;
                const double r2 = dz2 + dy * dy;
                if (r2 >= 1.0) continue;
                float* row = w.data() + std::size_t(j) * std::size_t(nx);
                for (int i = i0; i <= i1; ++i) {
                    const double dx = (g.origin.x + (i + 0.5) * g.voxel_size - e.centre.x) / e.radii.x;
                    const double d2 = r2 + dx * dx;
                    if (d2 >= 1.0) continue;
                    const double v = ellipsoid_weight(e, d2);
                    row[i] = std::max(row[i], float(v));
                }
            }
        }
        std::uint8_t* dst = out.data() + std::size_t(k) * std::size_t(nx) * std::size_t(ny);
        for (std::size_t q = 0; q < w.size(); ++q)
            dst[q] = std::uint8_t(std::lround(std::clamp(double(w[q]), 0.0, 1.0) * 255.0));
    });
    return out;
}

}  // namespace detail

core::Grid3<float> generate_cumulonimbus(const CumulonimbusParams& p) {
    validate_cumulonimbus(p);
    const core::GridGeometry g = cumulonimbus_geometry(p);
    const std::vector<Placed> placed = layout(p);
    std::vector<detail::Ellipsoid> ellipsoids;
    ellipsoids.reserve(placed.size());
    for (const Placed& pl : placed) ellipsoids.push_back(pl.e);

    // Layers whose centre is below the base stay empty; the first layer at or above it is
    // the flat base.
    const int first_layer = std::clamp(int(std::ceil(p.base_height / p.voxel_size - 0.5)), 0, p.grid.z);
    const double floor_z = g.centre(0, 0, first_layer < p.grid.z ? first_layer : p.grid.z - 1).z;
    std::vector<std::uint8_t> weights = detail::seed_field(g, ellipsoids, floor_z - 1e-9 * p.voxel_size);

    detail::Automaton ca(p.grid, std::move(weights), {p.p_ext, p.p_hum, p.p_act},
                         core::hash_seed(p.seed, kAutomatonTag));
    ca.init_vapour();
    std::vector<std::uint8_t> counts(g.cell_count(), 0);
    for (int t = 0; t < p.steps; ++t) ca.step(t >= p.steps - p.average_steps ? counts.data() : nullptr);

    core::Grid3<float> density(g);
    density.data =
        detail::smooth_density(p.grid, counts, p.average_steps, p.smoothing_radius, first_layer, p.density_gain);
    return density;
}

}  // namespace fulgur::cloud
