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

    /// Output directions the bake needs: 1 when scattering is isotropic (g == 0), since S
    /// then does not depend on direction; the scene's count otherwise.
    int effective_directions() const noexcept { return medium.g == 0.0 ? 1 : directions; }
};

/// Loads and validates a scene file.
Scene load_scene(const std::filesystem::path& path);

/// Parses a scene from JSON text; `file_name` appears in error messages and `base_dir`
/// resolves relative paths.
Scene parse_scene(std::string_view json_text, std::string_view file_name, const std::filesystem::path& base_dir = {});

/// The cloud density the scene describes (generated or loaded).
core::Grid3<float> make_density(const Scene& s);

/// The transport medium on the lighting grid (density box-filtered by lighting_downsample).
transport::LightingMedium make_lighting_medium(const Scene& s, const core::Grid3<float>& density);

/// The medium the solvers run in: the lighting grid refined by transport.refine (the
/// lighting medium itself when refine is 1).
transport::LightingMedium make_transport_medium(const Scene& s, const core::Grid3<float>& density);

}  // namespace fulgur::scene
