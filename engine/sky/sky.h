// fulgur::sky — the light of the sky on the cloud: the sun (or the moon, a dim sun) and the
// sky dome. Unlike lightning it does not change per frame, so it is solved once through the
// lattice, as Geist et al. 2004 light their clouds (section 5, Appendix A), cached on disk,
// and solved again only when the sun moves. docs/sky.md explains the model and the checks.
//
//   directional light -> exact single scattering S1 (and the uncollided fluence phi1) on the
//   transport grid -> lattice-Boltzmann fed with S1 for orders >= 2 -> S averaged onto the
//   lighting grid, per unit irradiance; the sky dome = many directional lights, two bases.
//
// Everything here is per unit irradiance (sun) or unit radiance (sky gradient ends): colour,
// irradiance and radiance scale the stored fields when they are composed (compose()), so a
// new moon brightness or sky colour needs no new solve; a new sun direction does.
#pragma once

#include "bake/bake.h"
#include "core/core.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <glm/vec3.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace fulgur::sky {

/// How a directional light is solved.
enum class Method {
    /// Exact single scattering (transport::single_scattering of the directional source, voxel
    /// averages) and the lattice for orders >= 2, fed with it (first_scattered and
    /// first_scattered_fluence), as solve::solve does for point lights. The default.
    Hybrid,
    /// Geist et al. as published: the light injected at the lattice boundary along the
    /// Appendix A decomposition of its direction, every order from the lattice (the
    /// uncollided beam too, on 18 lattice directions). `single` stays empty.
    Lattice,
    /// Every order by Monte Carlo from the box's boundary through the full-resolution density
    /// (sun_truth, sky_truth: the truth's estimator, SolveSettings::truth_paths per light; the
    /// media must hold the full density). single and multiple as Hybrid gives them.
    MonteCarlo,
};

/// "hybrid" | "lattice"; throws core::Error naming `where` otherwise.
Method parse_method(std::string_view s, std::string_view where);
std::string_view to_string(Method m) noexcept;

/// The processes a static solve is spread over (distributed::static_light_settings: the ranks
/// of an MPI run). Every process calls the same solve with the same arguments on the thread
/// that joined the run; each computes its share of the independent parts (the sky's dome
/// samples; the sun's single scattering and its order-2 Monte Carlo) and they exchange them,
/// so every process returns the same field, bit for bit the one-process solve.
class Processes {
public:
    virtual ~Processes() = default;
    virtual int rank() const = 0;
    virtual int size() const = 0;
    /// Process `root`'s `data` into `data` on every process (collective: all call it).
    virtual void share(std::span<float> data, int root) const = 0;
    /// Process 0's `value` on every process (collective; waiting processes do not spin).
    virtual int broadcast(int value) const = 0;
};

struct SolveSettings {
    Method method = Method::Hybrid;
    bool single = true;    ///< keep S1 (effects.single_scattering; computed anyway to feed the lattice)
    bool multiple = true;  ///< run the lattice (effects.multiple_scattering)
    transport::SingleScatteringOptions single_options;
    transport::LbSettings lattice;
    /// Directions sampling the sky dome (equal solid angles over the upper hemisphere). An
    /// accuracy/time knob: each is one exact single-scattering solve.
    int sky_samples = 32;
    /// > 0: the dome's orders 1 and 2 by Monte Carlo from the whole dome (transport::DomeSource,
    /// this many paths per basis) through the full-resolution density, in place of the
    /// sky_samples directions (no directions to band small clouds' shadows); the lattice for
    /// orders >= 3 as with directions. 0: the directions.
    std::uint64_t sky_paths = 0;
    /// The transport grid the solve runs on: the lighting grid refined by this (the media
    /// passed to the solves must be static_media's, whose refine it is).
    int refine = 1;
    /// Keep S on that transport grid (transport.static_light.grid "transport"): the media's
    /// lighting grid is then the transport grid itself (refine 1 between them), so nothing is
    /// averaged away and the truth tallies on the same grid. False: S averaged onto the
    /// scene's lighting grid.
    bool keep_transport_grid = false;
    /// 2: order 2 by the expected-value Monte Carlo of the second flight through the
    /// full-resolution density (order2_paths per sun; the sky's dome samples share them), the
    /// lattice for orders >= 3, as transport.lattice_boltzmann.exact_orders does for point
    /// lights. 1: the lattice for orders >= 2 (Hybrid only).
    int exact_orders = 1;
    std::uint64_t order2_paths = 400'000;
    std::uint64_t seed = 1;  ///< of the order-2 Monte Carlo (a solve is deterministic)
    /// Method::MonteCarlo: paths per light (the sun; each basis of the sky), drawn from `seed`,
    /// so the solve is the static truth (TruthOptions) of the same paths and seed.
    std::uint64_t truth_paths = 4'000'000;
    /// Set (transport.static_light.directions "camera", Method::MonteCarlo only): S toward this
    /// point (the scene's camera) from every voxel, one field (transport::MonteCarloOptions::
    /// toward) instead of the scene's output directions.
    std::optional<glm::dvec3> toward;
    /// Spreads the solve over several processes (the lattice too, through lattice.make_kernel);
    /// unset: this process alone. Not part of the cache keys: the result is the same.
    std::shared_ptr<const Processes> processes;
};

/// The scene's settings: solve::single_scattering_options, solve::lattice_settings and its
/// effects (the same accuracy knobs as the virtual-light bake), with transport.static_light's
/// refine and exact orders (where it leaves them 0: static_refine_for, and order 2 exact).
SolveSettings solve_settings(const scene::Scene& s, const core::Grid3<float>& density);
/// The output directions a static solve gives: one toward the camera (settings.toward), else
/// the scene's effective count.
int static_direction_count(const scene::Scene& s, const SolveSettings& settings);
/// transport.static_light.refine's default (0): the smallest divisor r of lighting.downsample
/// that makes a transport voxel at density 1 at most one optical depth thick (extinction x
/// lighting voxel / r <= 1), else lighting.downsample (the full resolution).
int static_refine_for(const scene::Scene& s, const core::Grid3<float>& density);
/// The media static solves run in: the lighting grid refined by solve_settings(s).refine, with
/// the full-resolution density when they solve order 2 exactly (or `full`). With
/// keep_transport_grid their lighting grid is that transport grid (refine 1).
///
/// When the scene declares rain, the rain is part of them (rain_media_density): the sun's,
/// moon's and sky's light reaches the rain through the cloud, is scattered by it, more than once,
/// and lights the cloud's base and the ground through it, in every solve of the static light and
/// its truth. The solvers have one set of optics, the cloud's, so the rain enters as cloud
/// of the same transport coefficient; sigma_t = extinction x density stays exact where cloud and
/// rain together pass density 1 (the media's extinction is raised and their density scaled).
/// No rain: the cloud alone, as the virtual-light bake and the strikes' solves always see it.
/// `rain`: cloud::make_rain of that density and the scene's rain, made here when null.
solve::Media static_media(const scene::Scene& s, const core::Grid3<float>& density,
                          const cloud::RainField* rain = nullptr);
solve::Media static_media(const scene::Scene& s, const core::Grid3<float>& density, bool full);
/// solve::make_media(s, density, refine, full) with the rain in it as above (the truth's media,
/// which tally on the lighting grid and need no transport grid of their own).
solve::Media make_static_media(const scene::Scene& s, const core::Grid3<float>& density, int refine, bool full,
                               const cloud::RainField* rain = nullptr);

/// The cloud density that stands for rain of extinction 1 (1/m) in the static light's media:
/// the density of equal transport coefficient sigma_a + sigma_s (1 - g) (the similarity
/// relation of diffusion theory; Wyman, Patterson and Wilson 1989),
///   rho = (1 - albedo_rain g_rain) / (kappa (1 - albedo g)),
/// kappa, albedo, g the cloud's. Drops scatter forward (g = 0.85 against the cloud's 0.6):
/// the rain of the default storm counts as 0.39 of its extinction. Its absorption comes out
/// lower than the rain's (0.39 x at equal albedo), which at albedo 0.99 is 0.4% of its extinction.
double rain_media_density(const transport::Medium& cloud, const cloud::RainParams& rain);

/// S of one light on the lighting grid, per unit irradiance (a sun) or unit radiance (a sky
/// basis), in W m^-2 sr^-1 per (W m^-2) or per (W m^-2 sr^-1).
struct LightField {
    transport::SourceField single;    ///< order 1 (Hybrid, single on); else empty
    transport::SourceField multiple;  ///< orders >= 2 (Hybrid) or all orders (Lattice); empty without a lattice solve
    int iterations = 0;               ///< lattice steps
    bool converged = true;
    /// The lattice's energy bookkeeping (transport::LbResult, W per step and W x steps):
    /// injected_total = absorbed_total + escaped_total + stored.
    double injected_per_step = 0.0, injected_total = 0.0, absorbed_total = 0.0, escaped_total = 0.0, stored = 0.0;
    /// Power scattered once in the cloud, sum of sigma_s phi1 h^3 (Hybrid; W per unit light).
    double first_scattered_power = 0.0;
    double seconds_single = 0.0, seconds_multiple = 0.0;
    bool empty() const noexcept { return single.data.empty() && multiple.data.empty(); }
};

/// Solves directional lights together (the result is linear in them: their sum) on
/// media.transport and averages S onto media.lighting. `directions`: the output directions
/// (transport::output_directions of the scene's effective count). Throws core::Error on bad
/// input (a zero direction, non-finite irradiance).
LightField solve_directional(const solve::Media& media, std::span<const transport::DirectionalSource> lights,
                             std::span<const glm::dvec3> directions, const SolveSettings& settings);

/// One direction of the sky dome, seen from the scene: `toward` points at the sky (z > 0).
struct DomeSample {
    glm::dvec3 toward{0.0, 0.0, 1.0};
    double solid_angle = 0.0;  ///< sr; the samples' solid angles sum to 2 pi
};
/// `count` directions over the upper hemisphere with equal solid angles (a Fibonacci
/// spiral in z = sin(elevation)), count >= 1.
std::vector<DomeSample> dome_samples(int count);

/// The sky dome's light: the response to each end of the gradient (scene::SkyDome), for unit
/// radiance: L_zenith(el) = zenith_weight(sin el), L_horizon(el) = 1 - zenith_weight(sin el).
/// A uniform sky has both ends equal, so it needs only their sum: `uniform` then holds it and
/// zenith/horizon stay empty (one lattice solve instead of two).
struct SkyField {
    LightField zenith, horizon, uniform;
};
/// The dome as settings.sky_samples directional lights (each an exact single scattering,
/// shared by both bases), then one lattice solve per basis. `uniform`: solve the sum only.
SkyField solve_sky(const solve::Media& media, bool uniform, std::span<const glm::dvec3> directions,
                   const SolveSettings& settings);

/// Transmittance from the sun to every voxel centre of `density` (the full-resolution
/// cloud) along -direction, through that density (sigma_t = extinction * rho; exact voxel
/// traversal): what the renderer's single scattering at full resolution multiplies by. Only
/// the voxels the renderer reads are computed: those within one voxel of the cloud (the ray
/// march interpolates it where the density is non-zero) and those on the grid's faces (the
/// ground's shadow looks it up where the ray to the sun enters the grid); the others hold 1.
core::Grid3<float> sun_transmittance(const core::Grid3<float>& density, double extinction, const glm::dvec3& direction);

/// The scene's sun transmittance: through its cloud (`density`, make_density's) and, when the
/// scene declares rain, through the rain too (`rain`: cloud::make_rain of that density, made
/// here when null): the rain's voxels are then computed as well, so the rain is lit through
/// the cloud and shadows the ground.
core::Grid3<float> sun_transmittance(const scene::Scene& s, const core::Grid3<float>& density,
                                     const glm::dvec3& direction, const cloud::RainField* rain = nullptr);

// ---------------------------------------------------------------------------------------
// The plan: what a scene's light needs and why

/// Every solve a scene triggers, and why (printable; docs/design.md#simulate-only-what-the-scene-calls-for): "no lightning means no
/// virtual-light bake at all; no sun means no sun solve; isotropic scattering needs one
/// output direction". The run-time effects (glow, ground) are listed too.
struct ScenePlan {
    /// The virtual-light bake (lightning on): its own plan. Absent: no bake, no .fgb.
    std::optional<bake::Plan> lightning;
    bool sun = false;          ///< a sun (or moon) solve
    bool sky = false;          ///< the sky dome's solves
    bool sky_uniform = false;  ///< a uniform sky: one lattice solve instead of two
    int directions = 1;        ///< output directions of every solve
    SolveSettings settings;    ///< how the sun and the sky are solved
    /// Counts: lights the bake solves (each a single scattering + a lattice solve or Monte
    /// Carlo), sun solves, and the sky's exact single scatterings and lattice solves.
    std::size_t virtual_lights = 0;
    int sun_solves = 0, sky_single_solves = 0, sky_lattice_solves = 0;
    std::vector<std::string> reasons;  ///< one line per decision, in order
    std::string to_text() const;
};

/// Plans the scene: throws core::Error naming the file and field when it asks for nothing
/// that lights the cloud (no lightning, no sun, no sky, or neither single nor multiple
/// scattering). The bake's part is bake::make_plan (with `options`).
ScenePlan plan_scene(const scene::Scene& s, const core::Grid3<float>& density, const bake::PlanOptions& options = {});

// ---------------------------------------------------------------------------------------
// Solving once: the cache

/// The key of a sun's or the sky's solve: bake::scene_key (density, medium, grids, transport
/// settings) + what is solved (the sun's direction, or the sky's form and samples) and how.
/// Irradiance, radiance and colours are not in it (the solves are per unit light).
basis::BakeKey sun_key(const scene::Scene& s, const core::Grid3<float>& density, const SolveSettings& settings,
                       const glm::dvec3& direction);
basis::BakeKey sky_key(const scene::Scene& s, const core::Grid3<float>& density, const SolveSettings& settings,
                       bool uniform);

/// A field of a light file, by name ("single", "zenith.multiple", ...).
struct NamedField {
    std::string name;
    transport::SourceField field;
};
/// Writes fields (one geometry and direction set) with their key, checksummed, atomically.
/// File format: docs/sky.md.
void write_light_file(const std::filesystem::path& path, const basis::BakeKey& key, std::span<const NamedField> fields);
/// What a light file must hold to stand in for a solve: the scene's lighting grid, its output
/// directions, and the names its fields may have.
struct LightFileShape {
    core::GridGeometry grid;
    std::vector<glm::dvec3> directions;
    std::vector<std::string> names;
};
/// Reads a light file: a regular file no larger than the shape allows (4 GiB without one),
/// every size validated against the file, the checksum, every value finite and within what a
/// solve writes. With `expected`, a file solved for another key is rejected ("stale": the
/// first differing line); with `shape`, one for another grid, other directions or with fields
/// the light does not have. Errors name the file and the byte offset.
std::vector<NamedField> read_light_file(const std::filesystem::path& path, const basis::BakeKey* expected = nullptr,
                                        const LightFileShape* shape = nullptr);

/// The scene's static light, per unit light.
struct StaticLight {
    std::optional<LightField> sun;             ///< per unit irradiance
    glm::dvec3 sun_direction{0.0, 0.0, -1.0};  ///< what `sun` was solved for
    std::optional<SkyField> sky;               ///< per unit radiance
};

/// A sun of unit irradiance travelling along `sun_direction` and the sky (uniform, or the
/// gradient's two ends), solved as load_or_solve solves them, with no cache: for studies and
/// tests that light a cloud by both.
StaticLight solve_static(const solve::Media& media, const glm::dvec3& sun_direction, bool sky_uniform,
                         std::span<const glm::dvec3> directions, const SolveSettings& settings);

/// Where solves are cached: `dir` (created when missing), or beside the scene file when
/// empty; nothing is cached when `enabled` is false or the scene has no file.
struct CacheOptions {
    bool enabled = true;
    std::filesystem::path dir;
};
/// The cache file of the scene's sun or sky ("sun" | "sky"): <dir>/<scene stem>.<kind>.fgl.
std::optional<std::filesystem::path> cache_path(const scene::Scene& s, const CacheOptions& cache,
                                                std::string_view kind);

/// The plan's solves: each light is read from its cache file when that is fresh, else solved
/// (and written). `say` is told what happens ("sun: solved in 0.4 s (no cache file)").
/// Over several processes (plan.settings.processes): every process calls it; process 0 alone
/// reads and writes the cache files and tells the others whether each light is solved, so a
/// light read from its file is returned on process 0 only, a solved one on every process.
StaticLight load_or_solve(const scene::Scene& s, const core::Grid3<float>& density, const solve::Media& media,
                          const ScenePlan& plan, const CacheOptions& cache = {},
                          const std::function<void(const std::string&)>& say = {});

// ---------------------------------------------------------------------------------------
// The truth: Monte Carlo from the boundary through the full-resolution density

struct TruthOptions {
    std::uint64_t paths = 4'000'000;  ///< per light (the sun; each end of the sky), in [1000, 2^34]
    std::uint64_t seed = 23;          ///< every light draws its own stream from it
    /// The sky's profile (zenith_weight) tabulated at this many values of sin(elevation)
    /// (transport::DomeSource), in [2, 2^20].
    int table = 1025;
    /// Set: S toward this point from every voxel (transport::MonteCarloOptions::toward); the
    /// directions passed must then be one. static_truth takes its plan's settings.toward.
    std::optional<glm::dvec3> toward;
    /// Set: also tally the light the cloud scatters onto these ground cells (the paths'
    /// crossings after one scattering or more: transport::MonteCarloOptions::ground).
    std::optional<transport::GroundTally> ground;
};
/// One light's truth in a solve's shape (single: order 1, multiple: orders >= 2), with the
/// Monte Carlo's own noise (relative L2 from two independent halves) and wall time.
struct TruthField {
    LightField field;
    transport::MonteCarloResult::Noise noise;
    transport::MonteCarloResult::CloudSums sums;  ///< whole-cloud totals with standard errors
    double seconds = 0.0;
    /// With TruthOptions::ground: the scattered light on its cells, and their power with its SE.
    transport::GroundIrradiance ground;
    transport::Estimate ground_power;
};
/// The sun (unit irradiance along `direction`) entering the grid's box, through media.full
/// (solve::make_media with the full-resolution density), tallied on media.lighting.
/// core::Error without the full-resolution density or with options out of range.
TruthField sun_truth(const solve::Media& media, const glm::dvec3& direction, std::span<const glm::dvec3> directions,
                     const TruthOptions& options = {});
/// A basis of the sky dome as a tabulated dome (transport::DomeSource, `table` values of
/// sin(elevation) from 0 to 1): the zenith end of the gradient (zenith_weight), the horizon end
/// (1 - zenith_weight) or the uniform sky (their sum, two values). The truth's and the solve's
/// Monte Carlo of the dome use it.
enum class DomeBasis { Zenith, Horizon, Uniform };
transport::DomeSource dome_basis(DomeBasis which, int table = 1025);
/// The sky dome's bases as solve_sky gives them (zenith and horizon ends of the gradient, or
/// their sum for a uniform sky), per unit radiance: radiance from every direction above the
/// horizon (transport::DomeSource), not the solve's sky_samples directions.
struct SkyTruth {
    SkyField field;
    std::vector<transport::MonteCarloResult::Noise> noise;     ///< per basis (zenith, horizon; or uniform)
    std::vector<transport::MonteCarloResult::CloudSums> sums;  ///< per basis, as `noise`
    double seconds = 0.0;
    std::vector<transport::GroundIrradiance> ground;  ///< per basis, as `noise` (TruthOptions::ground)
    std::vector<transport::Estimate> ground_power;    ///< per basis
};
SkyTruth sky_truth(const solve::Media& media, bool uniform, std::span<const glm::dvec3> directions,
                   const TruthOptions& options = {});
/// The plan's static light (its sun along `sun_direction`, its sky) by the truth, in the shape
/// load_or_solve gives, so a view can render it in place of the solves (a reference frame).
/// `noise`: each light's, in order (sun, then the sky's bases).
StaticLight static_truth(const ScenePlan& plan, const solve::Media& media, const glm::dvec3& sun_direction,
                         std::span<const glm::dvec3> directions, const TruthOptions& options = {},
                         std::vector<transport::MonteCarloResult::Noise>* noise = nullptr);
/// Empties the fields of `light` that `like` (the scene's solves) lacks: the parts its effects
/// switched off, so a truth renders what the solves would.
void keep_parts(StaticLight& light, const StaticLight& like);
/// The truth of the scene's solved static light `solved` (its sun's direction, its parts):
/// static_truth through the static media's full-resolution density when they hold it (their
/// order 2 is exact), else through media made for this call, then keep_parts.
StaticLight truth_of(const scene::Scene& s, const core::Grid3<float>& density, const ScenePlan& plan,
                     const solve::Media& media, const StaticLight& solved, std::span<const glm::dvec3> directions,
                     const TruthOptions& options = {},
                     std::vector<transport::MonteCarloResult::Noise>* noise = nullptr);

// ---------------------------------------------------------------------------------------
// Composing the colour the renderer draws

struct ComposeOptions {
    bool sun = true, sky = true;          ///< include each (run-time switches)
    bool sun_single = true;               ///< the sun's order 1 (false: drawn at full resolution)
    bool single = true, multiple = true;  ///< which orders (the sky's and the sun's)
};
/// S of the static light in colour on the lighting grid: for each output direction, rgb per
/// cell (x fastest): irradiance x colour x the sun's field + the sky's ends x their radiance
/// and colour. Empty (no directions) when nothing is included.
struct ColourField {
    core::GridGeometry geom;
    std::vector<glm::dvec3> directions;
    std::vector<std::vector<float>> rgb;  ///< per direction, 3 floats per cell
    bool empty() const noexcept { return rgb.empty(); }
};
ColourField compose(const StaticLight& light, const std::optional<scene::Sun>& sun,
                    const std::optional<scene::SkyDome>& sky, const ComposeOptions& options);
/// Relative L2 of `x` against `ref` (two compose() results of one shape) over the cells where
/// `density` (the lighting grid's) is > 0, every direction and channel; 0 when `ref` is empty.
double colour_error(const ColourField& x, const ColourField& ref, std::span<const float> density);

// ---------------------------------------------------------------------------------------
// Solving again when the sun moves

/// A sun solved for one direction: its field and its full-resolution transmittance.
struct SunSolve {
    glm::dvec3 direction{0.0, 0.0, -1.0};
    LightField field;
    core::Grid3<float> transmittance;  ///< sun_transmittance of the scene's density
    double seconds = 0.0;              ///< wall time of the solve (lattice + transmittance)
    /// A SunResolver's quick first answer (order 2 by the lattice, settings.exact_orders 2
    /// asked for): the refined solve of the same direction follows unless a newer request came.
    bool preview = false;
};
/// The scene's sun solve for `direction` (sun_transmittance included). Seconds.
SunSolve solve_sun(const scene::Scene& s, const core::Grid3<float>& density, const solve::Media& media,
                   const SolveSettings& settings, const glm::dvec3& direction);

/// The sun's (or the moon's) course over a day, for the time-of-day control: an equinox day
/// at a latitude whose noon sun stands at least 10 degrees above the scene's (and at least
/// 50), turned in azimuth so that it passes through the scene's sun in the afternoon (at
/// scene_hour). Away from the scene's elevation the light crosses another air mass (Kasten &
/// Young 1989; a clear atmosphere's optical depth per channel): a low sun is dimmer and
/// redder. docs/sky.md "Time of day".
struct SunCourse {
    scene::Sun scene_sun;
    double scene_elevation = 0.0, scene_azimuth = 0.0;  ///< degrees
    double latitude = 0.0;                              ///< degrees
    double azimuth_offset = 0.0;                        ///< degrees
    double scene_hour = 12.0;                           ///< solar time of the scene's sun
    double first_hour = 6.0, last_hour = 18.0;          ///< the sun at least 1 degree high
    /// The sun at solar time `hour` (clamped to [first_hour, last_hour]): direction, colour
    /// (luminance 1) and irradiance; at(scene_hour) is the scene's sun.
    scene::Sun at(double hour) const;
    /// Elevation and azimuth (degrees, the scene's convention) at `hour`.
    void angles(double hour, double& elevation_deg, double& azimuth_deg) const;
};
SunCourse sun_course(const scene::Sun& sun);

/// Solves the sun again on a worker thread whenever asked (the demo's time-of-day slider):
/// only the newest request matters, the caller keeps showing the old field until take()
/// returns the new one. With exact orders 2 it answers twice: first a preview with order 2 by
/// the lattice (a few times faster: docs/sky.md gives both latencies), then the refined solve,
/// unless a newer request came meanwhile. Thread-safe.
class SunResolver {
public:
    /// Keeps references to the arguments; they must outlive it. `threads`: the worker's share
    /// of the cores (>= 1).
    SunResolver(const scene::Scene& s, const core::Grid3<float>& density, const solve::Media& media,
                const SolveSettings& settings, int threads);
    ~SunResolver();
    SunResolver(const SunResolver&) = delete;
    SunResolver& operator=(const SunResolver&) = delete;
    /// Asks for the sun along `direction`; replaces a request not yet started.
    void request(const glm::dvec3& direction);
    /// The newest finished solve not taken yet; rethrows a solve's error.
    std::optional<SunSolve> take();
    /// A request is queued or being solved.
    bool busy() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::sky
