// fulgur::cloud — cloud density: the storm-cloud generator and density import/export.
//
// The generator follows Dobashi et al. 2000 ("A Simple, Efficient Method for Realistic
// Animation of Clouds"): a cellular automaton with three boolean states per cell
// (hum: vapour, act: phase-transition activation, cld: cloud), the growth rules
//   hum' = hum & !act,  cld' = cld | act,  act' = !act & hum & f_act(neighbours),
// stochastic extinction (cld' = cld & rnd > p_ext) and supply (hum' |= rnd < p_hum,
// act' |= rnd < p_act) whose probabilities are shaped by seed ellipsoids, then space-time
// averaging and smoothing to a continuous density in [0, 1]. The ellipsoids are placed to
// build a cumulonimbus: a flat base, a tall convective tower (with flanking towers), and an
// optional anvil with an overshooting top. docs/cloud.md explains the method and every
// parameter with pictures.
//
// Coordinates: z up, ground at z = 0, the grid centred horizontally on x = y = 0; the main
// tower rises from x = y = 0 and the wind (shear, anvil spread) blows towards +x.
// Deterministic for a given seed, whatever the thread count.
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fulgur::cloud {

/// Every parameter of the cumulonimbus generator; the scene file's "cloud.generator" object
/// sets them by the same names. Lengths in metres. validate_cumulonimbus() checks that they
/// are consistent; the defaults are the default storm's cloud (content/scenes/storm.json),
/// except the seed (7 there).
struct CumulonimbusParams {
    std::uint64_t seed = 1;         ///< everything random (layout and automaton) follows from it
    core::Int3 grid{144, 144, 80};  ///< density voxels (x, y, z): 18 x 18 x 10 km by default
    double voxel_size = 125.0;      ///< metres per voxel (all axes)

    // --- Shape (metres) ---------------------------------------------------------------
    /// Height of the flat cloud base (the condensation level). No density below it; the
    /// lowest cloudy layer is a broad, flat disc about tower_radius in radius.
    double base_height = 1500.0;
    /// Highest point of the cloud: the summit of the tower, or of the overshooting top
    /// when there is an anvil.
    double top_height = 9000.0;
    /// Horizontal radius of the convective tower at its base; the tower narrows slightly
    /// with height and, without an anvil, rounds off into a cauliflower dome at the top.
    double tower_radius = 2500.0;
    /// Convective cells (turret ellipsoids) bulging out of the tower's flanks; more cells
    /// give a lumpier, more cauliflower-like tower. 0 leaves a smooth column.
    int cells = 40;
    /// Horizontal displacement (+x) of the tower's top relative to its base (wind shear);
    /// the tower leans downwind. 0 = upright.
    double shear = 600.0;
    /// Smaller towers of the flanking line, upwind (-x) and to the side of the main tower,
    /// each lower than the last. 0 = a single-cell storm.
    int flanking_towers = 3;

    /// Anvil: a wide, flat cloud spreading at the top of the tower (the tropopause),
    /// thickest near the tower and thinner, more diffuse towards its edges.
    bool anvil = true;
    double anvil_radius = 6500.0;     ///< horizontal radius of the anvil (> tower_radius)
    double anvil_thickness = 1800.0;  ///< thickness of the anvil near the tower
    /// Downwind (+x) displacement of the anvil's centre from the top of the tower: anvils
    /// spread mostly downwind.
    double anvil_offset = 1500.0;
    /// Height of the overshooting top, the dome the updraft pushes above the anvil's flat
    /// top; the anvil's top is at top_height - overshoot. 0 = none. Used only with the anvil.
    double overshoot = 600.0;

    // --- Cellular automaton (Dobashi 2000) ------------------------------------------------
    // Each ellipsoid gives a seed weight w in [0, 1] (full inside, falling smoothly to 0 at
    // its surface); a cell's weight W is the maximum over the ellipsoids. Per cell and step:
    //   p_hum(W) = p_hum * W,  p_act(W) = p_act * W,  p_ext(W) = p_ext * (1 - W).
    /// Fraction of each seed ellipsoid's radius, in (0, 1], over which its weight falls from
    /// full to 0: small gives hard-edged, sharply outlined cumulus towers, 1 soft blobs.
    /// The anvil's ellipsoids get softer towards the anvil's edge whatever this is.
    double edge_softness = 0.5;
    int steps = 32;            ///< automaton steps (the first starts from vapour ~ W)
    double p_ext = 0.2;        ///< extinction probability where W = 0 (falls to 0 at W = 1)
    double p_hum = 0.2;        ///< vapour supply probability where W = 1
    double p_act = 0.02;       ///< activation supply probability where W = 1
    int average_steps = 4;     ///< the last average_steps steps are averaged (time window)
    int smoothing_radius = 1;  ///< radius (voxels) of the spatial smoothing kernel
    /// Density = min(1, density_gain * smoothed cloud fraction). Above 1 it fills the
    /// interior (dense core, soft edges); below 1 the whole cloud is thinner.
    double density_gain = 1.3;
};

/// Checks a parameter set; throws core::Error whose where() is the scene field, e.g.
/// "cloud.generator.anvil_radius", and whose reason says what is expected (base above
/// top, shape not fitting in the grid, anvil narrower than the tower, ...).
void validate_cumulonimbus(const CumulonimbusParams& p);

/// Grid geometry of a generated cloud: dims and voxel size from params, centred on x=y=0,
/// ground at z=0.
core::GridGeometry cumulonimbus_geometry(const CumulonimbusParams& p);

/// Generates the density (values in [0, 1], exactly 0 below base_height). Validates the
/// parameters first (validate_cumulonimbus). Bit-identical for a given parameter set
/// whatever core::thread_count() is.
core::Grid3<float> generate_cumulonimbus(const CumulonimbusParams& p);

/// Loads a density NRRD and validates it (3D float32, values in [0, 1]); errors name the
/// file and the offending voxel or field.
core::Grid3<float> load_density(const std::filesystem::path& path);

/// Saves a density as NRRD (float32), loadable by load_density, ParaView and 3D Slicer.
/// Throws core::Error (naming the voxel) if a value is outside [0, 1] or not finite, so a
/// saved density always loads.
void save_density(const std::filesystem::path& path, const core::Grid3<float>& density);

// ---------------------------------------------------------------------------------------
// OpenVDB import and export (vdb*.cpp). A file is read by OpenVDB in a child process under
// memory and time limits (vdb_child.cpp), its records checked by this one (vdb_parent.cpp);
// OpenVDB stays inside vdb_child.cpp and vdb.cpp's writer: nothing here names one of its types. docs/cloud.md, "OpenVDB clouds", explains the mapping and the filter.

/// How a float grid of a .vdb file becomes the engine's density grid (the scene file's
/// "cloud": {"vdb": ...} object sets these by the same names).
///
/// Geometry: the grid's index-to-world transform must be linear and axis-aligned (a scale
/// per axis, possibly different, and a translation); rotated, sheared, mirrored and
/// non-linear (frustum) transforms are refused. World units become metres times `scale`
/// (or the voxel is `voxel_size` metres along its smallest axis), `up` "y" turns a y-up file
/// (Houdini, EmberGen) to the engine's z-up (x stays, y becomes z, z becomes -y), then
/// `offset` moves it. The density grid covers the active voxels' bounding box (active tiles
/// included) with cubic voxels of `density_voxel_size` metres (default: the file's voxel in
/// metres, its smallest axis when anisotropic).
///
/// Filter: each density voxel is the average of the VDB's piecewise-constant field over the
/// voxel's box (a box filter, separable, weights = overlap lengths): it keeps the cloud's
/// total extinction (its integral) at any resolution and, unlike point sampling, does not
/// alias when the density grid is coarser; with the file's own voxel size and grid it is an
/// exact copy.
/// Largest .vdb file read (4 GiB), checked (core::check_readable_file) before opening.
inline constexpr std::uint64_t kMaxVdbFileBytes = std::uint64_t(1) << 32;
/// Default peak memory of a VDB load (16 GiB) when the caller gives none.
inline constexpr std::uint64_t kMaxVdbLoadBytes = std::uint64_t(16) << 30;

struct VdbImport {
    /// The float grid's name; empty: the float grid "density", or else the first float grid
    /// by name (OpenVDB lists a file's grids by name; the plan says which was taken).
    std::string grid;
    double scale = 1.0;               ///< metres per world unit of the file
    double voxel_size = 0.0;          ///< metres per file voxel (its smallest axis); 0: from scale
    double density_voxel_size = 0.0;  ///< the density grid's voxel, metres; 0: the file's voxel
    double density_scale = 1.0;       ///< multiplies every value; the result must lie in [0, 1]
    bool y_up = false;                ///< the file's +y is up
    glm::dvec3 offset{0.0};           ///< metres, added last
    /// Refuse a load whose peak memory (VdbInfo::load_bytes) exceeds this; the scene
    /// passes its memory limit ("limits.memory_gib").
    std::uint64_t max_bytes = kMaxVdbLoadBytes;
};

/// What load_vdb would read and make, from the file's grid descriptors and metadata alone
/// (no voxel is read): for sizing a load before doing it, and for the bake plan.
struct VdbInfo {
    std::string grid;                 ///< the chosen grid's name
    bool first_float_grid = false;    ///< chosen without a name ("density", or the first float grid)
    std::vector<std::string> grids;   ///< every grid of the file, "name (type)", by name
    core::Int3 source_dims;           ///< the active voxels' bounding box, in file voxels
    glm::dvec3 source_voxel{0.0};     ///< metres per file voxel along the engine's x, y, z
    std::uint64_t active_voxels = 0;  ///< the file's count (file_voxel_count)
    core::GridGeometry density;       ///< the density grid load_vdb returns
    std::uint64_t load_bytes = 0;     ///< peak memory of load_vdb (tree + dense copies)
    /// One line for the plan: the grid, why it was chosen, source and density grids, filter.
    std::string describe() const;
};

/// Reads the file's descriptors and metadata; throws core::Error naming the file (and the
/// grid) when the file is missing or not a VDB, the grid is missing or not float, empty, or
/// its transform cannot be mapped (see VdbImport), or the options do not fit the engine's
/// grid limits (core::validate_geometry).
VdbInfo inspect_vdb(const std::filesystem::path& path, const VdbImport& options);

/// The density grid of the file's grid (inspect_vdb's checks, then the voxels). Refuses
/// before allocating when inspect_vdb's load_bytes exceed options.max_bytes, and when the
/// tree turns out larger than its metadata said; values (after density_scale) outside
/// [0, 1] and a background other than 0 are refused naming the voxel or the grid.
core::Grid3<float> load_vdb(const std::filesystem::path& path, const VdbImport& options);

/// A grid save_vdb writes: a float grid on `values`' geometry (voxel (i,j,k)'s centre at
/// values.geom.centre(i,j,k), metres), every voxel active (constant blocks stored as tiles),
/// so its active bounding box is the whole grid and load_vdb returns `values` exactly.
struct VdbOutputGrid {
    std::string name;
    const core::Grid3<float>* values = nullptr;
    bool fog_volume = false;                                  ///< grid class fog volume (a density) instead of unknown
    std::vector<std::pair<std::string, std::string>> text;    ///< string metadata
    std::vector<std::pair<std::string, glm::dvec3>> vectors;  ///< vec3d metadata
    std::vector<std::pair<std::string, double>> numbers;      ///< double metadata
};

/// Writes the grids into one .vdb (atomically: core::AtomicFile) with `file_text` as
/// file-level metadata. Refuses non-finite values (core::check_finite) before writing.
void save_vdb(const std::filesystem::path& path, std::span<const VdbOutputGrid> grids,
              const std::vector<std::pair<std::string, std::string>>& file_text = {});

/// Height (z, metres) of the lowest voxel layer whose maximum density exceeds `threshold`;
/// the grid's top if none does.
double cloud_base_height(const core::Grid3<float>& density, float threshold = 0.05f);

/// Height (z, metres) of the upper face of the highest voxel layer whose maximum density
/// exceeds `threshold`; the grid's bottom if none does.
double cloud_top_height(const core::Grid3<float>& density, float threshold = 0.05f);

// ---------------------------------------------------------------------------------------
// Previews: quick looks at a density, for people and for docs (not a renderer).

/// An 8-bit RGB image, rows top to bottom.
struct Image {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgb;
};

enum class PreviewKind {
    SliceXZ,    ///< vertical slice through the grid's centre (y = middle), density in pseudo-colour
    TopMax,     ///< top-down maximum projection of the density along z, pseudo-colour
    SideDepth,  ///< side view along y: optical depth tau, shown as 1 - exp(-tau), grey
    SideLit,    ///< side view along y against a sky, lit by a sun from the upper left:
                ///< attenuated sunlight plus a flat ambient term, no multiple scattering
                ///< (a quick look at the shape, not the engine's renderer)
};

/// Renders a preview; `extinction` (1/m per unit density) is used by the side views. Each
/// voxel becomes `scale` x `scale` pixels. z points up in the side views, y up in the top view.
Image render_preview(const core::Grid3<float>& density, PreviewKind kind, double extinction = 0.004, int scale = 1);

/// Writes the previews in `kinds` side by side, bottom-aligned, in one PNG.
void write_preview_png(const std::filesystem::path& path, const core::Grid3<float>& density,
                       std::span<const PreviewKind> kinds, double extinction = 0.004, int scale = 1);

}  // namespace fulgur::cloud
