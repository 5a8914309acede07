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
#include "core/core.h"
#include "lightning/lightning.h"
#include "transport/transport.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fulgur::scene {

inline constexpr int kFormatVersion = 1;
/// Largest scene file read (1 MiB; the default storm is 2 kB): checked before reading.
inline constexpr std::uint64_t kMaxSceneBytes = std::uint64_t(1) << 20;

struct CloudSource {
    enum class Kind { Generator, File };
    Kind kind = Kind::Generator;
    cloud::CumulonimbusParams generator;  ///< used when kind == Generator
    std::filesystem::path file;           ///< NRRD density, used when kind == File (absolute)
};

/// Effects the scene calls for. Work for an effect that is off is not done (no solve, no
/// texture, no pass); DESIGN.md "Simulate only what the scene calls for".
struct Effects {
    bool lightning = true;            ///< lightning bolts and their virtual lights
    bool single_scattering = true;    ///< direct (first-scattered) light in the cloud
    bool multiple_scattering = true;  ///< orders >= 2 (transport solver in the bake)
    bool sun = false;                 ///< the scene's directional light
    bool glow = true;                 ///< glow quads around strokes (render)
    bool ground = true;               ///< ground plane lit by the flash (render)
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
    // monte_carlo
    std::uint64_t mc_paths = 2'000'000;  ///< paths per light
    std::uint64_t mc_seed = 1;
    int mc_batches = 32;  ///< batches for the per-voxel standard error
};

/// "limits": what a bake of the scene may cost before it is refused (docs/scene-format.md).
struct Limits {
    /// Peak memory, bytes; 0: three quarters of the machine's physical memory.
    double memory_bytes = 0.0;
    double bake_seconds = 24.0 * 3600.0;  ///< the bake's estimated wall time
};

struct Scene {
    std::filesystem::path path;  ///< the scene file ("" when parsed from memory)
    std::string name;
    transport::Medium medium;
    CloudSource cloud;
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
    std::optional<transport::DirectionalSource> sun;   ///< the "lights" entry of type "sun"
    Effects effects;
    lightning::LightningParams lightning;  ///< section "lightning": bolt shape, flash timing, schedule
    Limits limits;                         ///< section "limits"

    /// Output directions the bake needs: 1 when scattering is isotropic (g == 0), since S
    /// then does not depend on direction; the scene's count otherwise.
    int effective_directions() const noexcept { return medium.g == 0.0 ? 1 : directions; }
};

/// Loads and validates a scene file.
Scene load_scene(const std::filesystem::path& path);

/// Parses a scene from JSON text; `file_name` appears in error messages and `base_dir`
/// resolves relative paths.
Scene parse_scene(std::string_view json_text, std::string_view file_name, const std::filesystem::path& base_dir = {});

/// What baking the scene costs, estimated from the scene alone (for a cloud file, from its
/// NRRD header): nothing is allocated or solved. Memory is an upper estimate of the peak;
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
    std::size_t lights = 1;
    int threads = 1;
};
/// `lights`: the virtual-light count when known (the plan knows it; 1 before the density
/// exists); `threads`: bake workers (0: core::thread_count()).
Cost estimate_cost(const Scene& s, std::size_t lights = 1, int threads = 0);
/// The memory limit in bytes (limits.memory_bytes, or 3/4 of physical memory when 0).
double memory_limit(const Scene& s);
/// Throws core::Error naming "limits.memory_gib" or "limits.bake_hours", the estimate and
/// how to raise the limit, when the cost exceeds a limit.
void check_cost(const Scene& s, const Cost& c);

/// The cloud density the scene describes (generated or loaded). Refuses (check_cost) before
/// allocating when the scene's estimated cost exceeds its limits.
core::Grid3<float> make_density(const Scene& s);

/// The transport medium on the lighting grid (density box-filtered by lighting_downsample).
transport::LightingMedium make_lighting_medium(const Scene& s, const core::Grid3<float>& density);

/// The medium the solvers run in: the lighting grid refined by transport.refine (the
/// lighting medium itself when refine is 1).
transport::LightingMedium make_transport_medium(const Scene& s, const core::Grid3<float>& density);

}  // namespace fulgur::scene
