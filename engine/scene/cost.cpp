// What a bake costs, from the scene alone (scene.h, Cost): memory per stage and a lower bound
// on time, checked against the scene's limits before anything is allocated or solved.
#include "scene/scene.h"

#include "basis/fgb.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>

namespace fulgur::scene {

namespace {

// Bytes per density cell while the generator runs: its weights, two automaton states and the
// averaged counts (1 byte each), the smoothing's two float passes and the density (4 each).
constexpr double kGeneratorBytesPerCell = 16.0;
// A loaded NRRD: the density and the copy the range check and downsampling may make.
constexpr double kFileBytesPerCell = 8.0;
// Lattice-Boltzmann: D3Q19, float distributions, the next step's and the inflow (3 x 19),
// plus per-site extinctions and sources (8 floats).
constexpr double kLbBytesPerCell = (3.0 * 19.0 + 8.0) * 4.0;
// Monte Carlo tallies: single, multiple and fluence sums plus the batch mean and M2 (double).
constexpr double kMcBytesPerCellDirection = 6.0 * 8.0;

// Lower bounds on time, one thread of a 2-core x86-64 (the fastest measured case of each:
// the default storm at downsample 6 costs 4x more per cell-direction in single scattering,
// 2x per site-step in the lattice and 8x per path in Monte Carlo; docs/hostile-inputs.md).
constexpr double kSingleSecondsPerCellDirection = 1e-7;
constexpr double kLbSecondsPerSiteStep = 0.5e-9;  // per site and lattice direction
constexpr double kMcSecondsPerPath = 2e-7;

core::Int3 divided(core::Int3 d, int f) { return {std::max(1, d.x / f), std::max(1, d.y / f), std::max(1, d.z / f)}; }
double volume(core::Int3 d) { return double(d.x) * double(d.y) * double(d.z); }

// The per-strike transport grid's dims (strike_refine, as runtime::FramePipeline solves on).
core::Int3 strike_transport_dims(const Scene& s, const Cost& c) {
    return divided(c.density_dims, s.lighting_downsample / std::max(1, strike_refine(s, s.quality)));
}

// A strike's solve at run time (runtime::solve_strike): its single scattering's paths, then
// its multiple scattering by Monte Carlo paths or by the lattice on the per-strike transport
// grid (order 2 from the single scattering's own paths when exact).
double strike_seconds(const Scene& s, const Cost& c) {
    const Quality& q = s.quality;
    if (q.preset == Quality::Preset::Paper) return 0.0;
    double t = double(q.single_paths) * kMcSecondsPerPath;
    if (q.multiple == "monte_carlo") {
        t += double(q.multiple_paths) * kMcSecondsPerPath;
    } else if (q.multiple == "lattice") {
        const core::Int3 d = strike_transport_dims(s, c);
        const double steps = double(std::max({d.x, d.y, d.z}));
        t += volume(d) * 19.0 * steps * kLbSecondsPerSiteStep;
    }
    return t;
}

}  // namespace

std::optional<transport::GroundTally> strike_ground_cells(const Scene& s, const core::GridGeometry& lighting) {
    if (!s.effects.ground || !s.effects.lightning) return std::nullopt;
    return transport::ground_cells_around(lighting, s.lightning.bolt.ground_height, 20000.0, 2048);
}

Cost estimate_cost(const Scene& s, std::size_t lights, int threads) {
    Cost c;
    c.lights = std::max<std::size_t>(lights, 1);
    c.threads = threads > 0 ? threads : core::thread_count();
    const bool file = s.cloud.kind != CloudSource::Kind::Generator;
    // The NRRD header or the VDB's metadata alone (bounded, checked): no voxel is read.
    std::uint64_t vdb_load_bytes = 0;
    double voxel = s.cloud.generator.voxel_size;  // metres per density voxel
    if (s.cloud.kind == CloudSource::Kind::Vdb) {
        const cloud::VdbInfo v = inspect_vdb_cloud(s);
        c.density_dims = v.density.dims;
        voxel = v.density.voxel_size;
        vdb_load_bytes = v.load_bytes;
    } else if (file) {
        const core::GridGeometry g = core::read_nrrd_header(s.cloud.file).geom;
        c.density_dims = g.dims;
        voxel = g.voxel_size;
    } else {
        c.density_dims = s.cloud.generator.grid;
    }
    c.lighting_dims = divided(c.density_dims, s.lighting_downsample);
    c.transport_dims = divided(c.density_dims, s.lighting_downsample / std::max(1, s.transport.refine));
    const double nd = volume(c.density_dims), nl = volume(c.lighting_dims), nt = volume(c.transport_dims);
    const double dirs = double(s.effective_directions());
    const bool multiple = s.effects.multiple_scattering;
    const bool lb = s.transport.solver == TransportSettings::Solver::LatticeBoltzmann;

    // A VDB load peaks with its sparse tree and dense copies (cloud::VdbInfo::load_bytes).
    c.density_bytes = std::max(vdb_load_bytes, std::uint64_t(nd * (file ? kFileBytesPerCell : kGeneratorBytesPerCell)));
    c.media_bytes = std::uint64_t((nl + nt) * 4.0 * 2.0);
    // A worker holds its light's single and multiple S on the transport grid (float), the
    // stored bases on the lighting grid and the Haar transform's double buffers.
    double worker = 2.0 * dirs * nt * 4.0 + 2.0 * dirs * nl * 4.0 + 2.0 * nl * 8.0;
    if (multiple) worker += lb ? nt * kLbBytesPerCell : nt * dirs * kMcBytesPerCellDirection;
    c.per_thread_bytes = std::uint64_t(worker);
    c.memory_bytes = c.density_bytes + c.media_bytes + std::uint64_t(c.threads) * c.per_thread_bytes;

    double t = nt * dirs * kSingleSecondsPerCellDirection;
    if (multiple) {
        // The lattice needs at least as many steps as the grid is cells across for light to
        // cross it; Monte Carlo costs at least its paths.
        const double steps = double(std::max({c.transport_dims.x, c.transport_dims.y, c.transport_dims.z}));
        t += lb ? nt * 19.0 * steps * kLbSecondsPerSiteStep : double(s.transport.mc_paths) * kMcSecondsPerPath;
        // Order 2 exact: its expected-value paths through the full density, per light.
        if (lb && s.transport.lb_exact_orders == 2) t += double(s.transport.lb_order2_paths) * kMcSecondsPerPath;
    }
    c.seconds_per_light = t;
    c.seconds = t * double(c.lights) / double(std::min<std::size_t>(std::size_t(c.threads), c.lights));
    c.seconds_per_strike = strike_seconds(s, c);
    if (s.quality.preset != Quality::Preset::Paper) {
        // runtime::StrikeLight: single and multiple S of two groups (channel, branches), every
        // direction (one when tallied toward the camera), float; kept on the transport grid
        // too, with the frame's copy there (every direction).
        const double per_field = (s.quality.toward_camera ? 1.0 : dirs) * 4.0;
        double bytes = 4.0 * per_field * nl;
        if (s.quality.keep_transport_grid)
            bytes += (4.0 * per_field + dirs * 4.0) * volume(strike_transport_dims(s, c));
        // The light the cloud scatters onto the ground, per group, on the strike's ground cells
        // (runtime::strike_ground: up to 2048 a side, 32 MB a strike on a continent-sized grid).
        const core::GridGeometry lighting{c.lighting_dims, voxel * s.lighting_downsample, glm::dvec3(0.0)};
        if (const auto ground = strike_ground_cells(s, lighting)) bytes += 2.0 * 4.0 * double(ground->cells());
        c.strike_light_bytes = std::uint64_t(bytes);
    }
    return c;
}

double memory_limit(const Scene& s) {
    if (s.limits.memory_bytes > 0.0) return s.limits.memory_bytes;
    const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
    return pages > 0 && page > 0 ? 0.75 * double(pages) * double(page) : double(std::uint64_t(8) << 30);
}

void check_cost(const Scene& s, const Cost& c) {
    const std::string file = s.file_name();
    auto dims = [](core::Int3 d) {
        return std::to_string(d.x) + " x " + std::to_string(d.y) + " x " + std::to_string(d.z);
    };
    // The bases' file holds at most kMaxFgbCells lighting cells: a finer grid (a small
    // density_voxel_size, a large generator grid at a small downsample) is refused here, from
    // the sizes alone, not after the density (gigabytes) is made.
    if (s.effects.lightning && volume(c.lighting_dims) > double(basis::kMaxFgbCells))
        throw core::Error(file + ": lighting.downsample",
                          std::to_string(s.lighting_downsample) + ": the lighting grid would be " +
                              dims(c.lighting_dims) + " cells (density " + dims(c.density_dims) + "), over the " +
                              std::to_string(basis::kMaxFgbCells) +
                              " a bake file holds; raise lighting.downsample or make the density coarser");
    const double mem = memory_limit(s);
    if (double(c.memory_bytes) > mem)
        throw core::Error(
            file + ": limits.memory_gib",
            "the bake would need about " + core::format_bytes(double(c.memory_bytes)) + " (density " +
                dims(c.density_dims) + ": " + core::format_bytes(double(c.density_bytes)) + "; lighting " +
                dims(c.lighting_dims) + " and transport " + dims(c.transport_dims) +
                " media: " + core::format_bytes(double(c.media_bytes)) + "; " + std::to_string(c.threads) +
                " worker(s) x " + core::format_bytes(double(c.per_thread_bytes)) + "), over the limit of " +
                core::format_bytes(mem) + (s.limits.memory_bytes > 0.0 ? "" : " (3/4 of physical memory)") +
                "; raise \"limits\": {\"memory_gib\": ...}, use fewer threads, or a coarser grid or downsample");
    // A frame loop holds the density, the media, a solved strike's light and the one being
    // solved: a quality that keeps each strike on a transport grid that would not fit is refused
    // here, not after minutes of solving.
    // The solve's Monte Carlo tallies its paths on that grid, per thread and per group (channel,
    // branches): ~1 GB of the 1.7 GB the default storm's strike takes kept on 250 m voxels.
    const double tally_bytes = double(c.threads) * 2.0 * kMcBytesPerCellDirection * double(s.effective_directions()) *
                               volume(strike_transport_dims(s, c));
    const double run_bytes = double(c.density_bytes + c.media_bytes) + 2.0 * double(c.strike_light_bytes) + tally_bytes;
    if (s.quality.keep_transport_grid && run_bytes > mem)
        throw core::Error(
            file + ": /quality/grid",
            "\"transport\" keeps each solved strike on the transport grid: about " +
                core::format_bytes(double(c.strike_light_bytes)) + " per strike, " + core::format_bytes(run_bytes) +
                " with the solve's tallies, the density and the media, over the limit of " + core::format_bytes(mem) +
                "; use \"lighting\", a smaller quality.refine, or raise \"limits\": {\"memory_gib\": ...}");
    if (c.seconds > s.limits.bake_seconds)
        throw core::Error(file + ": limits.bake_hours",
                          "the bake would take at least " + core::format_seconds(c.seconds) + " (" +
                              std::to_string(c.lights) + " light(s) x " + core::format_seconds(c.seconds_per_light) +
                              " on " + std::to_string(c.threads) + " thread(s)), over the limit of " +
                              core::format_seconds(s.limits.bake_seconds) +
                              "; raise \"limits\": {\"bake_hours\": ...} or ask for less (paths, grid, directions)");
    if (c.seconds_per_strike > s.limits.strike_seconds)
        throw core::Error(file + ": limits.strike_minutes",
                          "each strike's solve (quality \"" + std::string(to_string(s.quality.preset)) +
                              "\": " + std::to_string(s.quality.single_paths) + " single-scattering paths" +
                              (s.quality.multiple == "monte_carlo"
                                   ? " + " + std::to_string(s.quality.multiple_paths) + " multiple-scattering paths"
                                   : std::string()) +
                              ") would take at least " + core::format_seconds(c.seconds_per_strike) +
                              " on one thread, over the limit of " + core::format_seconds(s.limits.strike_seconds) +
                              "; lower quality.single_paths / multiple_paths or raise \"limits\": "
                              "{\"strike_minutes\": ...}");
}

}  // namespace fulgur::scene
