// fulgur::bake — turns a scene into its .fgb (Dobashi et al. 2007, sections 5-6):
// virtual lights, per-light basis intensities (exact single scattering + multiple
// scattering by lattice-Boltzmann, or Monte Carlo at reference quality), 3D Haar,
// thresholding, and the checksummed file.
//
// A bake is planned from the scene's declared effects and its data, and the plan says what
// will be simulated and why (isotropic scattering: one output direction; no multiple
// scattering: no transport solve; no sun: no sun solve; lights whose contribution to the
// cloud is negligible: dropped and counted). Execution is a list of independent per-light
// jobs followed by a merge (docs/design.md#scaling-past-one-machine). A light's S comes from the
// solver layer (solve/solve.h), which the run time and the sky share.
//
// THIS HEADER IS THE CONTRACT between the bake module and the apps (fulgur-bake, the demo,
// fulgur-shot, benchmarks). Changing it is fine when the implementation needs it; keep it
// small and documented.
#pragma once

#include "basis/basis.h"
#include "core/core.h"
#include "scene/scene.h"
#include "solve/solve.h"
#include "transport/transport.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace fulgur::bake {

/// 64-bit hash of every bake-relevant scene parameter and the canonical description it is
/// computed from (one "key=value" per line); stored in the .fgb so a stale file is detected
/// and explained. A density loaded from a file contributes a hash of its bytes.
/// (basis::BakeKey: hash = hash_description(description).)
basis::BakeKey scene_key(const scene::Scene& s, const core::Grid3<float>& density);

/// What a bake will do, and why. Printable (to_text) before baking; `--dry-run` prints only this.
struct Plan {
    core::GridGeometry lighting;                ///< lighting grid
    basis::VirtualLightGrid lights;             ///< virtual-light grid
    std::vector<glm::dvec3> output_directions;  ///< the baked output directions
    int directions = 1;                         ///< output_directions.size()
    bool single = true;                         ///< direct term baked
    bool multiple = true;                       ///< transport solver runs
    std::uint32_t components = 1;               ///< 2: single and multiple stored separately
    std::string solver;                         ///< "lattice_boltzmann", "monte_carlo" or "none"
    std::vector<std::string> reasons;           ///< one line per decision ("g = 0: 1 direction instead of 26", ...)
    std::uint64_t raw_bytes = 0;                ///< uncompressed float32 size of all bases
    std::uint64_t expected_bytes = 0;           ///< estimated compressed size (0: not estimated)
    double expected_seconds = 0.0;              ///< estimated wall time on this machine (0: not estimated)
    int threads = 1;                            ///< worker threads the bake will use
    scene::Cost cost;                           ///< memory and a lower bound on time, before solving
    int sample_lights = 0;                      ///< lights solved for expected_* (16, fewer on large grids)
    bool single_measured = false;               ///< cost.seconds from the single scattering measured on a sample
    basis::FgbMetadata metadata;                ///< what the file will hold (key, grids, directions)
    std::string to_text() const;
};
struct PlanOptions {
    /// Time and compress 16 sample lights (fewer when their lower-bound cost, Plan::cost,
    /// passes a minute) spread over the grid to estimate the bake's time
    /// and size; about a second. false: expected_* stay 0.
    bool estimate = true;
    int threads = 0;  ///< 0: core::thread_count()
    /// Told, one line each, what the estimate is doing when it will take more than a few
    /// seconds (the single scattering's probe, each sample light): a plan can take a minute.
    std::function<void(const std::string&)> on_progress;
};
/// Throws core::Error when the scene asks for nothing to bake (lightning off, or neither
/// single nor multiple scattering) or its cloud is empty.
Plan make_plan(const scene::Scene& s, const core::Grid3<float>& density, const PlanOptions& options = {});

/// The uncompressed bases of virtual light l as the bake stores them (FgbMetadata order:
/// component-major, then direction), before the Haar transform. For NRRD export and tests.
transport::SourceField solve_light(const scene::Scene& s, const solve::Media& media, const Plan& plan,
                                   std::uint32_t light);

/// Progress callback: lights done, lights total, seconds elapsed.
using Progress = std::function<void(std::size_t done, std::size_t total, double seconds)>;

/// What a bake measured (written by fulgur-bake --report as JSON).
struct Report {
    double seconds_total = 0.0;
    double seconds_single = 0.0, seconds_multiple = 0.0, seconds_compress = 0.0, seconds_write = 0.0;
    std::size_t lights = 0, lights_dropped = 0;
    std::uint64_t raw_bytes = 0, file_bytes = 0, coefficients_kept = 0;
    double compression_ratio = 0.0;
    double relative_l2_error = 0.0;  ///< compressed vs uncompressed bases, over all lights and directions
    double mean_solver_iterations = 0.0, max_solver_iterations = 0.0;
    std::size_t unconverged = 0;        ///< lights whose solver hit its iteration cap
    double max_dropped_fraction = 0.0;  ///< largest first-scattered power fraction of a dropped light
    int threads = 1;
    std::size_t lights_resumed = 0;  ///< lights taken from a checkpoint (their figures included)
};

// ---------------------------------------------------------------------------------------
// A bake in parts (docs/distributed.md): the plan's lights are solved in chunks of
// consecutive lights by this process's threads and, through Helpers, by other processes; a
// checkpoint keeps finished chunks so a killed bake resumes; the file is written in light
// order, so it is byte-identical however the work was split.

/// What one virtual light's job produced: its block as the file stores it and the figures
/// the Report sums.
struct LightResult {
    basis::EncodedBlock block;
    double seconds_single = 0.0, seconds_multiple = 0.0, seconds_compress = 0.0;  ///< CPU seconds
    double ref2 = 0.0, err2 = 0.0;   ///< squared L2 of the stored bases and of their compression error
    double dropped_fraction = -1.0;  ///< first-scattered power fraction of a dropped light; -1: kept
    std::uint64_t coefficients = 0;  ///< coefficients kept
    std::int32_t iterations = -1;    ///< lattice steps (-1: no lattice solve)
    bool converged = true;
};

/// Solves, compresses and encodes lights [begin, end) of the plan with plan.threads threads
/// (each light single-threaded, as in bake()): a distributed bake's unit of work. In light
/// order.
std::vector<LightResult> bake_lights(const scene::Scene& s, const solve::Media& media, const Plan& plan,
                                     std::uint32_t begin, std::uint32_t end);

/// Serialized results (the figures, and the blocks when `with_blocks`), for messages between
/// processes and the checkpoint. decode_results checks every length and that the lights are
/// begin, begin+1, ...; errors name `where` and the byte offset.
std::vector<std::uint8_t> encode_results(std::span<const LightResult> results, bool with_blocks);
std::vector<LightResult> decode_results(std::span<const std::uint8_t> bytes, bool with_blocks, std::uint32_t begin,
                                        std::uint32_t end, const std::string& where);

/// Consecutive lights [begin, end).
struct Chunk {
    std::uint32_t begin = 0, end = 0;
    std::uint32_t size() const noexcept { return end - begin; }
};

/// Other processes taking part in a bake (distributed::bake implements it over MPI). bake()
/// calls poll() from the thread that called it, repeatedly, while its worker threads solve.
class Helpers {
public:
    virtual ~Helpers() = default;
    /// Worker threads of all helpers together (for the chunk size).
    virtual int threads() const = 0;
    /// Serves the helpers without blocking: hands out the chunks `next` gives (nullopt: no
    /// work left, the helper is released) and passes the chunks they finished to `deliver`.
    /// Returns true once every helper is released (all their results delivered); sets `busy`
    /// when it did anything.
    virtual bool poll(const std::function<std::optional<Chunk>()>& next,
                      const std::function<void(Chunk, std::vector<LightResult>&&)>& deliver, bool& busy) = 0;
};

struct BakeOptions {
    /// Keeps finished chunks in this directory (each a partial .fgb and its figures) and
    /// resumes from the chunks it holds, after checking them (checksums, the scene key, the
    /// plan's metadata, the light ranges): a corrupt or foreign checkpoint is refused with a
    /// core::Error naming the file. Removed once the file is written. Empty: no checkpoint.
    std::filesystem::path checkpoint;
    /// Called after each chunk is stored in the checkpoint, with the lights it then holds.
    std::function<void(std::size_t lights)> on_checkpoint;
    Helpers* helpers = nullptr;  ///< other processes solving chunks (none: this one alone)
    std::uint32_t chunk = 0;     ///< lights per chunk (0: from the thread count, at most 64)
};

/// The checkpoint directory beside `out`: "<out>.ckpt".
std::filesystem::path checkpoint_path(const std::filesystem::path& out);

/// Bakes the scene into `out` (atomically: a partial file never replaces a good one).
Report bake(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& out,
            const Progress& progress = {});
Report bake(const scene::Scene& s, const core::Grid3<float>& density, const Plan& plan,
            const std::filesystem::path& out, const Progress& progress = {});
/// The same with a checkpoint and helpers. Progress counts this run's lights (a resumed bake
/// starts from the lights the checkpoint lacks).
Report bake(const scene::Scene& s, const core::Grid3<float>& density, const Plan& plan,
            const std::filesystem::path& out, const BakeOptions& options, const Progress& progress = {});

/// The scene's default .fgb path (next to the scene: <scene>.fgb).
std::filesystem::path default_fgb_path(const scene::Scene& s);

/// What a .fgb baked from this scene must hold in its header (the plan's metadata: key,
/// grids, directions, lights, compression), for basis::FgbReader::check_metadata.
basis::FgbMetadata expected_metadata(const scene::Scene& s, const core::Grid3<float>& density);

/// True if `fgb` exists, is valid and was baked from this scene (hash and header geometry
/// match the plan's). `why`
/// receives the reason when false (missing, corrupt, stale: which parameter changed).
bool up_to_date(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& fgb,
                std::string* why = nullptr);

/// Bakes the scene into `fgb` unless it is up_to_date. Returns the report of the bake it
/// ran, or nothing when the file was already fresh. `on_stale` is called with up_to_date's
/// reason just before baking (e.g. to tell the user why a bake starts).
std::optional<Report> bake_if_stale(const scene::Scene& s, const core::Grid3<float>& density,
                                    const std::filesystem::path& fgb, const Progress& progress = {},
                                    const std::function<void(const std::string& why)>& on_stale = {});

}  // namespace fulgur::bake
