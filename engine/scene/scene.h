// fulgur::scene — scene files (JSON): what a scene contains and what it asks to simulate.
//
// A scene declares the medium, the cloud (generated or loaded), the grids, the lights and
// the effects it needs. Loading is strict: unknown keys, wrong types and out-of-range
// values are rejected with a core::Error naming the file, the field path and the allowed
// range. Relative paths inside a scene are relative to the scene file. The format is
// documented in docs/scene-format.md; content/scenes/storm.json is the default scene.
#pragma once

#include "basis/compression.h"
#include "basis/virtual_lights.h"
#include "cloud/cloud.h"
#include "cloud/rain.h"
#include "cloud/subvoxel.h"
#include "core/core.h"
#include "lightning/lightning.h"
#include "transport/transport.h"

#include <glm/vec3.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fulgur::scene {

inline constexpr int kFormatVersion = 1;
/// Largest scene file read (1 MiB; the default storm is 2 kB): checked before reading.
inline constexpr std::uint64_t kMaxSceneBytes = std::uint64_t(1) << 20;

struct CloudSource {
    enum class Kind { Generator, File, Vdb };
    Kind kind = Kind::Generator;
    cloud::CumulonimbusParams generator;  ///< used when kind == Generator
    /// The NRRD density (kind == File) or the .vdb file (kind == Vdb), absolute.
    std::filesystem::path file;
    cloud::VdbImport vdb;  ///< used when kind == Vdb: grid, scale, resampling ("cloud": {"vdb": ...})
    /// "cloud.detail": billows finer than the voxels carved into the cloud's edges (any
    /// source; none when absent: no noise, no erosion, the density as loaded).
    std::optional<cloud::SubvoxelDetail> detail;
};

/// Effects the scene calls for. Work for an effect that is off is not done (no solve, no
/// texture, no pass); docs/design.md#simulate-only-what-the-scene-calls-for.
struct Effects {
    bool lightning = true;            ///< lightning bolts and their virtual lights
    bool single_scattering = true;    ///< direct (first-scattered) light in the cloud
    bool multiple_scattering = true;  ///< orders >= 2 (transport solver in the bake)
    bool sun = false;                 ///< the scene's sun (or moon); default: on when it has one
    bool sky = false;                 ///< the sky dome's light; default: on when it has a sky
    bool glow = true;                 ///< glow quads around strokes (render)
    bool glare = true;                ///< the eye's glare around the drawn channel (render::Settings::glare)
    bool ground = true;               ///< ground plane lit by the flash (render)
};

/// Luminance of a linear-RGB colour (Rec. 709 weights): what the scene's colours are
/// normalized to (1), so that irradiance and radiance carry the magnitude.
inline double luminance(const glm::dvec3& c) noexcept { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

/// Direction sunlight travels for a sun at `elevation_deg` above the horizon and
/// `azimuth_deg` (counter-clockwise from +x toward +y, as seen from the scene): minus the
/// unit vector toward the sun.
glm::dvec3 sun_direction(double elevation_deg, double azimuth_deg) noexcept;
/// Elevation and azimuth (degrees) of the sun whose light travels along `direction` (unit).
void sun_angles(const glm::dvec3& direction, double& elevation_deg, double& azimuth_deg) noexcept;

/// A "lights" entry of type "sun": a directional light from outside the grid. A moon is a
/// dim sun (its irradiance), usually with a cooler colour.
struct Sun {
    glm::dvec3 direction{0.0, 0.0, -1.0};  ///< propagation direction (unit)
    double irradiance = 1.0;               ///< E, W/m^2 on a plane perpendicular to the light
    glm::dvec3 colour{1.0};                ///< linear RGB, luminance 1: the light is E * colour
    std::string name;                      ///< free text ("sun", "moon"); shown by the plan
    transport::DirectionalSource source() const noexcept { return {direction, irradiance}; }
};

/// The sky dome: radiance arriving from every direction above the horizon, a gradient in
/// the elevation el of the direction it comes from,
///     L(el) = horizon + (zenith - horizon) * sqrt(sin el)        (per colour channel),
/// uniform when zenith == horizon. The renderer draws the same function as the background,
/// so the sky the camera sees is the sky that lights the cloud. Below the horizon: nothing
/// (the ground's reflected light is not part of the sky light).
struct SkyDome {
    double zenith_radiance = 0.0;    ///< W m^-2 sr^-1
    glm::dvec3 zenith_colour{1.0};   ///< linear RGB, luminance 1
    double horizon_radiance = 0.0;   ///< W m^-2 sr^-1
    glm::dvec3 horizon_colour{1.0};  ///< linear RGB, luminance 1
    double star_radiance = 2e-5;     ///< brightest stars drawn in the background (0: none)
    glm::dvec3 zenith() const noexcept { return zenith_radiance * zenith_colour; }
    glm::dvec3 horizon() const noexcept { return horizon_radiance * horizon_colour; }
    /// Profile of the gradient: the weight of the zenith value at elevation sin_el (>= 0).
    static double zenith_weight(double sin_el) noexcept { return sin_el > 0.0 ? std::sqrt(sin_el) : 0.0; }
};

/// Multiple-scattering solver settings as written in the scene.
struct TransportSettings {
    enum class Solver { LatticeBoltzmann, MonteCarlo };
    Solver solver = Solver::LatticeBoltzmann;
    /// single_scattering.tolerance: accuracy knob of the exact single scattering
    /// (transport::SingleScatteringOptions::tolerance; docs/transport.md tabulates error vs time).
    double ss_tolerance = 1e-3;
    /// "refine": single scattering and the multiple-scattering solver run on the lighting grid
    /// refined by this factor (a divisor of lighting.downsample; voxels lighting/refine wide)
    /// and their S is averaged onto the lighting grid. The lattice's error in optically thick
    /// voxels and the coarse medium's error fall with the voxel size (docs/lattice-boltzmann.md,
    /// "Refined transport grid"); the solve costs about refine^4 more. 1: the lighting grid.
    int refine = 1;
    // lattice_boltzmann
    std::string lb_collision = "corrected";  ///< "corrected" (energy-conserving) or "published"
    std::string lb_absorption = "physical";  ///< "physical" (absorbed energy leaves) or "conservative" (paper)
    /// "saturate" (exact-chord mapping, one collision per voxel crossing) or
    /// "diffusion_matched" (over-relaxed in optically thick voxels; docs/lattice-boltzmann.md)
    std::string lb_thick_voxels = "diffusion_matched";
    double lb_tolerance = 1e-4;  ///< steady state: relative change per step
    int lb_max_iterations = 4000;
    /// "exact_orders": the scattering orders solved exactly before the lattice takes over. 1:
    /// exact single scattering, the lattice for orders >= 2 (Geist's coupling). 2: order 2 as
    /// well, by the expected-value Monte Carlo of the second flight through the full-resolution
    /// density (lb_order2_paths paths per solve), the lattice for orders >= 3: the lattice's
    /// angular error falls on the smoother, dimmer higher orders (docs/lattice-boltzmann.md).
    int lb_exact_orders = 1;
    std::uint64_t lb_order2_paths = 50'000;
    /// "static_light": how the sun's, moon's and sky's light is solved (once per scene and
    /// direction, cached): its own transport-grid refinement and exactly solved orders, as
    /// `refine` and lattice_boltzmann.exact_orders are for the bake's lights. 0: the default,
    /// refine from the medium's optical depth per lighting voxel (sky::static_refine_for) and
    /// order 2 exact. docs/sky.md measures them against the static light's truth.
    int static_refine = 0;
    int static_exact_orders = 0;
    /// "grid": where the static light's S is kept, solved, cached and drawn. Lighting (false):
    /// averaged onto the lighting grid, as the bake's lights. Transport (true): on the
    /// transport grid it is solved on (the lighting grid refined by static_refine), so the
    /// renderer reads S where the light falls over less than a lighting voxel (at the cloud's
    /// surface) at refine^3 the memory and resolve work (docs/sky.md measures both against
    /// Cycles).
    bool static_keep_transport_grid = false;
    /// "solver": how the static light is solved. Lattice (false): exact single scattering,
    /// order 2 by Monte Carlo, the lattice for orders >= 3 (static_exact_orders). Monte Carlo
    /// (true): every order by the truth's estimator (sky::sun_truth, sky::sky_truth: paths from
    /// the box's boundary through the full-resolution density), static_paths per light; cached
    /// like any solve, so it is paid once per scene and sun direction (docs/sky.md).
    bool static_monte_carlo = false;
    std::uint64_t static_paths = 4'000'000;
    /// "directions": which output directions the static light's S is solved for. Baked (false):
    /// the scene's output directions, between which the renderer interpolates toward any
    /// camera. Camera (true): toward the scene's camera from every voxel (one field, no
    /// interpolation; exact from that camera only, so for still shots): needs the Monte Carlo
    /// solver, and a new camera position is a new solve (docs/sky.md).
    bool static_toward_camera = false;
    /// Order-2 Monte Carlo paths of a static solve with exact orders 2 (a sun; the sky's dome
    /// samples share them by their weights).
    std::uint64_t static_order2_paths = 400'000;
    /// The sky dome: `static_sky_paths` 0 samples it as `static_sky_samples` directional lights
    /// of equal solid angle (each an exact single scattering); > 0 computes its orders 1 and 2
    /// by Monte Carlo from the whole dome (that many paths per end of the gradient) feeding
    /// the lattice for orders >= 3, with no directions to band the shadows.
    int static_sky_samples = 32;
    std::uint64_t static_sky_paths = 2'000'000;
    // monte_carlo
    std::uint64_t mc_paths = 2'000'000;  ///< paths per light
    std::uint64_t mc_seed = 1;
    int mc_batches = 32;  ///< batches for the per-voxel standard error
};

/// "quality": how a frame's lightning S is made, a preset and its knobs (docs/presets.md).
/// Every preset uses the same bake (the bases are the fallback while a strike's own solve is
/// not ready); they differ in what the run time computes once per strike, ahead of time, on
/// a worker thread.
struct Quality {
    enum class Preset {
        Paper,        ///< Dobashi 2007: the splat onto virtual lights and the bases, single + multiple
        Hybrid,       ///< the bases' multiple scattering + each strike's exact single scattering
        PerStrike,    ///< each strike solved directly: exact single scattering + the lattice
        PerStrikeMc,  ///< each strike by Monte Carlo, single and multiple, at modest path counts
        Instant,      ///< each strike by Monte Carlo started when it is known, blended in as it converges
        Reference,    ///< each strike by Monte Carlo through the full density (offline quality)
    };
    Preset preset = Preset::Paper;
    /// Per strike (not paper): expected-value Monte Carlo paths of the single scattering.
    std::uint64_t single_paths = 250'000;
    /// Per strike: "none" (the bases' multiple scattering: hybrid), "lattice" (per_strike) or
    /// "monte_carlo" (reference), with multiple_paths paths.
    std::string multiple = "none";
    std::uint64_t multiple_paths = 0;
    /// Strikes scheduled to start within this many seconds are solved ahead of time.
    double lookahead = 1.0;
    /// The per-strike solve's transport grid: the lighting grid refined by at least this factor
    /// (a divisor of lighting.downsample; transport.refine when that is finer); 0: as the
    /// bake. A finer per-strike lattice buys accuracy at run time without a slower bake.
    int refine = 0;
    /// The per-strike lattice's exactly solved orders (1 or 2, as
    /// transport.lattice_boltzmann.exact_orders); 0: the scene's, as the bake. Order 2 comes
    /// from the single scattering's own paths (their expected-value second flight).
    int exact_orders = 0;
    /// Where a solved strike's S is kept (scene "grid"): false ("lighting") averages it onto
    /// the lighting grid, where the frame mixes it with the bases; true ("transport") also keeps
    /// it on the per-strike transport grid, and each lit frame then carries S on that grid too
    /// (runtime::Frame::fine: the bases' part upsampled, the solved strikes' own light at that
    /// resolution) for the renderer. Presets that solve strikes ahead only (not paper, not
    /// instant) and a per-strike transport grid finer than the lighting grid (quality.refine or
    /// transport.refine above 1). docs/presets.md measures what it buys against Cycles and what
    /// it costs.
    bool keep_transport_grid = false;
    /// Which directions a solved strike's S is tallied at (scene "directions"): false
    /// ("baked") the scene's output directions; true ("camera") toward the scene's camera from
    /// every voxel (transport::MonteCarloOptions::toward), one field the frame adds into every
    /// output direction so the renderer takes it as it takes any strike: exact from that camera only
    /// (a still shot's setting). Presets whose per-strike solve is Monte Carlo only
    /// (toward_camera_problem). docs/presets.md measures it against Cycles.
    bool toward_camera = false;
    /// Instant: the progressive solve of a strike stops once the relative noise of its S
    /// (single + multiple, over the cloud) is at most this, or at single_paths /
    /// multiple_paths paths, whichever comes first.
    double target_noise = 0.02;
    /// Instant: the largest relative change (L2 over the cloud) of a strike's shown light from
    /// one frame to the next as newer estimates replace older ones: each frame moves the shown
    /// light toward the latest estimate by at most this. 0.25 stays well below what the flash's
    /// own intensity does between two frames at 60 fps (a return stroke's 12 ms decay: -75%),
    /// and fades the first estimate in over about 3 frames (docs/presets.md measures the cost).
    double max_change_per_frame = 0.25;
    /// Instant: rays per point of the near-field correction added to the bases' frame of a
    /// strike's strokes (runtime::NearField): what the splat cannot represent next to the
    /// channel, from a local model, so a strike's frames before its first estimate are not the
    /// paper frame. 0: none (docs/presets.md measures 32 and more).
    int near_field_rays = 0;
    /// Instant: how the correction is made. "diffusion": the strike's own light replaces the
    /// bases' (runtime::StrikeDiffusion: single scattering by rays from its points, multiple by
    /// a flux-limited diffusion solve; a bake storing single and multiple scattering as one
    /// basis falls back to "kernel"); "kernel": NearField's local model next to the channel.
    std::string near_field_multiple = "kernel";
    /// Instant, "diffusion": rays per point of the strike's single scattering cast through the
    /// cloud's full-resolution density (the truth's medium: the channel's light is cut off where
    /// the cloud's base and edges are, not where a lighting voxel's mean density is); its
    /// first-scattered light feeds the diffusion solve. 0: the lighting grid's cast of
    /// near_field_rays rays.
    int near_field_fine_rays = 0;
};

/// Every preset's name in scene files, indexed by Quality::Preset, cheapest first.
inline constexpr std::array<std::string_view, 6> kQualityPresets = {"paper",         "hybrid",  "per_strike",
                                                                    "per_strike_mc", "instant", "reference"};
/// The presets a running frame loop can switch to: all but reference, whose per-strike solve
/// takes minutes.
inline constexpr std::span<const std::string_view> kInteractiveQualityPresets{kQualityPresets.data(), 5};
static_assert(std::size_t(Quality::Preset::Reference) == kQualityPresets.size() - 1);

/// The preset's name in scene files (kQualityPresets).
std::string_view to_string(Quality::Preset p) noexcept;
/// The preset with its default knobs; throws core::Error naming `where` for an unknown name.
Quality quality_preset(std::string_view name, std::string_view where = "quality");
/// Why `q` cannot solve its strikes toward the camera (Quality::toward_camera), or empty: that
/// needs a preset that solves strikes ahead (not paper, not instant) by Monte Carlo alone (its
/// multiple scattering "monte_carlo", or "none" where the bases give it; the lattice solves
/// fixed directions).
std::string toward_camera_problem(const Quality& q);

/// "camera": where the scene is seen from. Only the view depends on it: no bake, solve or cache
/// does (it is not part of the scene key). Either a look-at camera (position, target, up) or an
/// orbit around a target (azimuth counter-clockwise from +x toward +y, elevation above the
/// horizontal, distance); an orbit's unset target and distance are the default view's
/// (view::scene_camera: the cloud's centre at a third of its height, 1.1 x the cloud's largest
/// extent away). docs/scene-format.md, "camera".
struct CameraSpec {
    enum class Kind { LookAt, Orbit };
    Kind kind = Kind::Orbit;
    glm::dvec3 position{0.0}, target{0.0};            ///< LookAt: metres
    glm::dvec3 up{0.0, 0.0, 1.0};                     ///< LookAt: not parallel to target - position
    double azimuth_deg = -90.0, elevation_deg = 6.0;  ///< Orbit
    std::optional<glm::dvec3> orbit_target;           ///< Orbit: default, the cloud's centre
    std::optional<double> distance;                   ///< Orbit: metres; default, 1.1 x the cloud's extent
    double vertical_fov_deg = 50.0;
    bool operator==(const CameraSpec&) const = default;
};

/// The orbit a camera leaves to the cloud: its target at the centre of `density`'s box at a
/// third of its height, its distance `distance_factor` x the box's largest extent.
void default_orbit(const core::GridGeometry& density, double distance_factor, glm::dvec3& target, double& distance);
/// Where the camera stands: a look-at's position, or an orbit's (target and distance defaulted by
/// default_orbit at 1.1; no camera: the default orbit). view::scene_camera places it the same.
glm::dvec3 camera_position(const std::optional<CameraSpec>& spec, const core::GridGeometry& density);

/// Parses a "camera" object given on its own (fulgur-shot --camera, the demo's --camera): JSON
/// text holding one object, validated as a scene's "camera"; errors name `source` and the field.
CameraSpec parse_camera(std::string_view json_text, std::string_view source);
/// A camera as a command line gives it (`option`, e.g. "--camera"): JSON text holding the
/// object (first non-blank character '{'), else the name of a file holding it (read up to
/// kMaxSceneBytes). Errors name the option or the file, and the field.
CameraSpec camera_argument(std::string_view value, std::string_view option);
/// The camera as the JSON object a scene's "camera" holds: numbers as the shortest text that
/// reads back exactly (digits 0), or to `digits` significant digits.
std::string camera_json(const CameraSpec& c, int digits = 0);

/// "limits": what a bake of the scene may cost before it is refused (docs/scene-format.md).
struct Limits {
    /// Peak memory, bytes; 0: three quarters of the machine's physical memory.
    double memory_bytes = 0.0;
    double bake_seconds = 24.0 * 3600.0;  ///< the bake's estimated wall time
    /// One strike's solve at run time (quality presets other than paper), estimated on one
    /// thread: a frame loop waits for it, so a runaway path count is refused before it starts.
    double strike_seconds = 600.0;
};

struct Scene {
    std::filesystem::path path;  ///< the scene file ("" when parsed from memory)
    /// The scene file as messages name it: its path, or "scene" when parsed from memory.
    std::string file_name() const { return path.empty() ? std::string("scene") : path.string(); }
    std::string name;
    transport::Medium medium;
    CloudSource cloud;
    /// "rain": shafts below the base of the cloud's raining columns (cloud/rain.h), drawn by
    /// the renderer and shadowing the sun and the ground; none when absent (no cost).
    std::optional<cloud::RainParams> rain;
    int lighting_downsample = 4;  ///< lighting grid = density grid box-filtered by this factor
    int directions = 26;          ///< output directions n_dir: 1, 6, 18 or 26
    TransportSettings transport;
    basis::VirtualLightParams virtual_lights;  ///< "virtual_lights": the grid of paper section 5
    basis::CompressionParams compression;      ///< "compression": Haar threshold and storage precision
    /// "compression.components": store the single- and the multiple-scattering part of each
    /// basis separately ("separate", default: the run time can show either, at about twice
    /// the file size) or summed ("combined"). Only meaningful when both effects are on.
    bool separate_components = true;
    /// "virtual_lights.drop_below": a virtual light whose light scattered by the cloud (first
    /// scattering, sigma_s * uncollided fluence summed over the cloud) is below this fraction
    /// of its emitted power is dropped from the bake (stored with no coefficients). 0 keeps all.
    double drop_below = 1e-4;
    std::vector<transport::PointSource> point_lights;  ///< "lights" of type "point"
    std::optional<Sun> sun;                            ///< the "lights" entry of type "sun" (or moon)
    std::optional<SkyDome> sky;                        ///< section "sky"
    Effects effects;
    lightning::LightningParams lightning;  ///< section "lightning": bolt shape, flash timing, schedule
    /// "lightning.colour": the flash's colour (bolt, glow, the light it scatters in the cloud),
    /// linear RGB of luminance 1; bluish white by default (nitrogen and hydrogen lines).
    glm::dvec3 lightning_colour = kLightningColour;
    static constexpr glm::dvec3 kLightningColour{0.9473, 0.9881, 1.2733};
    Quality quality;  ///< "quality": how frames are lit (a preset name, or an object with "preset" and knobs)
    Limits limits;    ///< section "limits"
    std::optional<CameraSpec> camera;  ///< section "camera" (unset: the default view)

    /// Output directions the bake needs: 1 when scattering is isotropic (g == 0), since S
    /// then does not depend on direction; the scene's count otherwise.
    int effective_directions() const noexcept { return medium.g == 0.0 ? 1 : directions; }
};

/// Loads and validates a scene file.
Scene load_scene(const std::filesystem::path& path);

/// Parses a scene from JSON text; `file_name` appears in error messages and `base_dir`
/// resolves relative paths.
Scene parse_scene(std::string_view json_text, std::string_view file_name, const std::filesystem::path& base_dir = {});

/// The refinement of the per-strike transport grid a quality solves strikes on: at least the
/// bake's (transport.refine); q.refine where it is finer and divides lighting.downsample (a
/// preset's default may not; a scene's own quality.refine is checked when read).
int strike_refine(const Scene& s, const Quality& q) noexcept;

/// The point a strike solved under `q` is tallied toward (transport::MonteCarloOptions::toward),
/// or none for the baked directions: the scene's camera (camera_position) when q.toward_camera,
/// none at g = 0, where S is the same toward every point and the one baked direction is it.
/// The pipeline's solves and the truth they are checked against both take it from here.
std::optional<glm::dvec3> strike_toward(const Scene& s, const Quality& q, const core::GridGeometry& density);
/// The same for the sun's, moon's and sky's S (transport.static_light.directions "camera",
/// solved by Monte Carlo).
std::optional<glm::dvec3> static_toward(const Scene& s, const core::GridGeometry& density);

/// The ground cells a strike's scattered light is gathered on (transport::ground_cells_around:
/// the lighting grid's footprint and 20 km around, at most 2048 a side, 2^22 cells, 16 MB a
/// group); none when the scene draws no ground or has no lightning.
std::optional<transport::GroundTally> strike_ground_cells(const Scene& s, const core::GridGeometry& lighting);

/// What baking the scene costs, estimated from the scene alone (for a cloud file, from its
/// NRRD header or VDB metadata): nothing is allocated or solved. Memory is an upper estimate of the peak;
/// time is a lower bound (per-cell and per-path costs measured on a 2-core machine, the
/// fastest case each: the real bake takes 1-4x longer), so a refusal is never a guess.
struct Cost {
    core::Int3 density_dims, lighting_dims, transport_dims;
    std::uint64_t density_bytes = 0;     ///< density grid and the generator's working arrays
    std::uint64_t media_bytes = 0;       ///< lighting and transport media
    std::uint64_t per_thread_bytes = 0;  ///< one bake worker: solver state, bases, Haar transform
    std::uint64_t memory_bytes = 0;      ///< peak: density + media + threads x per_thread
    double seconds_per_light = 0.0;      ///< lower bound, one worker
    double seconds = 0.0;                ///< lower bound: lights x per light / threads
    double seconds_per_strike = 0.0;     ///< lower bound of one strike's solve, one thread (0: paper)
    /// One solved strike's light as the run time keeps it, plus the frame's copy of S on the
    /// per-strike transport grid when the quality keeps that grid (0: paper).
    std::uint64_t strike_light_bytes = 0;
    std::size_t lights = 1;
    int threads = 1;
};
/// `lights`: the virtual-light count when known (the plan knows it; 1 before the density
/// exists); `threads`: bake workers (0: core::thread_count()).
Cost estimate_cost(const Scene& s, std::size_t lights = 1, int threads = 0);
/// The memory limit in bytes (limits.memory_bytes, or 3/4 of physical memory when 0).
double memory_limit(const Scene& s);
/// Throws core::Error naming "limits.memory_gib", "limits.bake_hours" or
/// "limits.strike_minutes", the estimate and how to raise the limit, when the cost exceeds a
/// limit.
void check_cost(const Scene& s, const Cost& c);

/// The scene's VDB cloud (cloud.kind must be Vdb) as cloud::inspect_vdb sees it, from the
/// file's metadata alone; errors name the scene file and the field ("/cloud/vdb", or
/// "/cloud/grid" for a named grid that is missing or not float).
cloud::VdbInfo inspect_vdb_cloud(const Scene& s);

/// The cloud density the solvers integrate: the one the scene describes (generated or
/// loaded) with its sub-voxel detail's voxel means (cloud::detailed_density) when it declares
/// one. Refuses (check_cost) before allocating when the scene's estimated cost exceeds its
/// limits.
core::Grid3<float> make_density(const Scene& s);

/// The cloud density before its sub-voxel detail (what the renderer erodes per ray-march
/// sample); make_density() when the scene declares no detail.
core::Grid3<float> make_undetailed_density(const Scene& s);

/// make_density() from make_undetailed_density()'s result, without generating or loading
/// the cloud again: the scene's detail applied (a copy when it declares none).
core::Grid3<float> add_detail(const Scene& s, const core::Grid3<float>& undetailed);

/// The transport medium on the lighting grid (density box-filtered by lighting_downsample).
transport::LightingMedium make_lighting_medium(const Scene& s, const core::Grid3<float>& density);

/// The medium the solvers run in: the lighting grid refined by transport.refine (the
/// lighting medium itself when refine is 1).
transport::LightingMedium make_transport_medium(const Scene& s, const core::Grid3<float>& density);

}  // namespace fulgur::scene
