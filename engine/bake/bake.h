// fulgur::bake — turns a scene into its .fgb (Dobashi et al. 2007, sections 5-6):
// virtual lights, per-light basis intensities (exact single scattering + multiple
// scattering by lattice-Boltzmann, or Monte Carlo at reference quality), 3D Haar,
// thresholding, and the checksummed file.
//
// A bake is planned from the scene's declared effects and its data, and the plan says what
// will be simulated and why (isotropic scattering: one output direction; no multiple
// scattering: no transport solve; no sun: no sun solve; lights whose contribution to the
// cloud is negligible: dropped and counted). Execution is a list of independent per-light
// jobs followed by a merge (DESIGN.md, "Scaling past one machine").
//
// THIS HEADER IS THE CONTRACT between the bake module and the apps (fulgur-bake, the demo,
// fulgur-shot, benchmarks). Changing it is fine when the implementation needs it; keep it
// small and documented.
#pragma once

#include "basis/basis.h"
#include "core/core.h"
#include "scene/scene.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace fulgur::bake {

/// 64-bit hash of every bake-relevant scene parameter and the canonical description it is
/// computed from (one "key=value" per line); stored in the .fgb so a stale file is detected
/// and explained. A density loaded from a file contributes a hash of its bytes.
struct SceneKey {
    std::uint64_t hash = 0;
    std::string description;
};
SceneKey scene_key(const scene::Scene& s, const core::Grid3<float>& density);

/// What a bake will do, and why. Printable (to_text) before baking; `--dry-run` prints only this.
struct Plan {
    core::GridGeometry lighting;         ///< lighting grid
    basis::VirtualLightGrid lights;      ///< virtual-light grid
    int directions = 1;                  ///< output directions actually baked
    bool single = true;                  ///< direct term baked
    bool multiple = true;                ///< transport solver runs
    std::string solver;                  ///< "lattice_boltzmann", "monte_carlo" or "none"
    std::vector<std::string> reasons;    ///< one line per decision ("g = 0: 1 direction instead of 26", ...)
    std::uint64_t raw_bytes = 0;         ///< uncompressed float32 size of all bases
    std::uint64_t expected_bytes = 0;    ///< estimated compressed size
    double expected_seconds = 0.0;       ///< estimated wall time on this machine
    std::string to_text() const;
};
Plan make_plan(const scene::Scene& s, const core::Grid3<float>& density);

/// Progress callback: lights done, lights total, seconds elapsed.
using Progress = std::function<void(std::size_t done, std::size_t total, double seconds)>;

/// What a bake measured (written by fulgur-bake --report as JSON).
struct Report {
    double seconds_total = 0.0;
    double seconds_single = 0.0, seconds_multiple = 0.0, seconds_compress = 0.0, seconds_write = 0.0;
    std::size_t lights = 0, lights_dropped = 0;
    std::uint64_t raw_bytes = 0, file_bytes = 0, coefficients_kept = 0;
    double compression_ratio = 0.0;
    double relative_l2_error = 0.0;      ///< compressed vs uncompressed bases, over all lights and directions
    double mean_solver_iterations = 0.0, max_solver_iterations = 0.0;
};

/// Bakes the scene into `out` (atomically: a partial file never replaces a good one).
Report bake(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& out,
            const Progress& progress = {});

/// The scene's default .fgb path (next to the scene: <scene>.fgb).
std::filesystem::path default_fgb_path(const scene::Scene& s);

/// True if `fgb` exists, is valid and was baked from this scene (hash matches). `why`
/// receives the reason when false (missing, corrupt, stale: which parameter changed).
bool up_to_date(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& fgb,
                std::string* why = nullptr);

}  // namespace fulgur::bake
