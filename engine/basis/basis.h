// fulgur::basis — virtual lights, basis intensities and their compressed storage
// (Dobashi et al. 2007, sections 5 and 6): the virtual-light grid, the 3D Haar transform,
// thresholding, and the .fgb baked file. docs/basis.md explains the choices, and
// docs/fgb-format.md specifies the file byte by byte.
//
//  * Virtual-light grid (paper section 5): build_virtual_light_grid().
//  * Haar: HaarTransform<T>, an orthonormal 3D transform for any grid size (non-standard
//    or standard decomposition of an "unbalanced" 1D Haar, exact for constants on any length).
//  * Compression: compress_coefficients() / compress_light() keep the coefficients above a
//    threshold (absolute, relative to the basis norm, or by energy kept), sorted by
//    decreasing magnitude, with the paper's gamma; values in float32 or float16.
//  * The .fgb file: FgbWriter (blocks from independent jobs, any order), merge_fgb()
//    (concatenate, check, index), FgbReader / load_fgb() (validate everything).
//  * Export to NRRD of a basis or of a weighted sum of bases, raw or reconstructed.
//
// A bake is "a list of per-light jobs, then a merge" (DESIGN.md "Scaling past one machine"):
// a job compresses lights [a, b) with compress_light() and writes them with an FgbWriter for
// that range (a partial file), or hands the CompressedLight objects to a shared writer;
// merge_fgb() joins partial files without touching their blocks.
#pragma once

#include "core/core.h"
#include "transport/transport.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fulgur::basis {

// =======================================================================================
// Virtual-light grid (paper section 5)

/// Spacing of the virtual-light grid (paper section 5).
struct VirtualLightParams {
    double h_usr = 1000.0;            ///< base interval (m): horizontal spacing, and vertical above the cloud base
    double epsilon = 1e-7;            ///< Eq. 4 bound on 1/r_l^2 - 1/r_{l+1}^2 below the base (1/m^2)
    double margin = 1000.0;           ///< horizontal margin around the cloud's footprint (m)
    double ground_height = 0.0;       ///< lowest layer of virtual lights (m)
    double density_threshold = 0.05;  ///< a voxel belongs to the cloud when its density exceeds this
};

/// Checks every field (finite, in range); throws core::Error naming `where`.field.
void validate(const VirtualLightParams& p, std::string_view where);

/// Upper bound on the number of virtual lights a grid may have (light indices are 32-bit in
/// the .fgb file; far below that, a bake would not finish anyway).
inline constexpr std::size_t kMaxVirtualLights = std::size_t(1) << 22;

/// The non-uniform (rectilinear) virtual-light grid: node coordinates per axis, ascending.
/// Light l = i + nx * (j + ny * k) sits at (x[i], y[j], z[k]).
struct VirtualLightGrid {
    std::vector<double> x, y, z;
    double cloud_base = 0.0;     ///< z of the cloud's bottom (a node of z: z[base_layer])
    double cloud_top = 0.0;      ///< z of the cloud's top (z.back() >= cloud_top)
    std::size_t base_layer = 0;  ///< index in z of the cloud base; layers below follow Eq. 4

    std::size_t count() const noexcept { return x.size() * y.size() * z.size(); }
    std::size_t index(std::size_t i, std::size_t j, std::size_t k) const noexcept {
        return i + x.size() * (j + y.size() * k);
    }
    glm::dvec3 position(std::size_t l) const noexcept {
        const std::size_t nx = x.size(), ny = y.size();
        return {x[l % nx], y[(l / nx) % ny], z[l / (nx * ny)]};
    }
    bool operator==(const VirtualLightGrid&) const = default;
};

/// Builds the virtual-light grid for a cloud (paper section 5, details in docs/basis.md):
///  * footprint: the x-y bounding box of the voxels whose density exceeds
///    p.density_threshold (voxel boxes, not centres), widened by p.margin on every side;
///    x and y nodes are spaced exactly h_usr, centred on the footprint, and cover it
///    (at least 2 nodes per axis);
///  * cloud base z_cld / top: bottom face of the lowest and top face of the highest voxel
///    layer that holds cloud. Nodes z_cld + k h_usr, k = 0..K, with z_cld + K h_usr >= top
///    (virtual lights fill the cloud volume: lightning starts inside clouds);
///  * below the base, distances r_l measured downward from z_cld: r_1 = h_usr (Eq. 4 is
///    undefined at r_0 = 0), then r_{l+1} = max(r_l + h_usr, R) with R the largest r
///    satisfying Eq. 4, 1/r_l^2 - 1/R^2 <= epsilon (R infinite when 1/r_l^2 <= epsilon);
///    the last layer is ground_height exactly; a layer closer than h_usr above it is
///    removed (so the last interval is in [h_usr, 2 h_usr) unless the base itself is
///    within h_usr of the ground).
/// Errors (core::Error): an empty cloud (no voxel above the threshold), a cloud base below
/// ground_height, invalid parameters, more than kMaxVirtualLights lights.
VirtualLightGrid build_virtual_light_grid(const core::Grid3<float>& density, const VirtualLightParams& p);

// =======================================================================================
// Haar transform

/// How the 1D transform is applied in 3D (docs/basis.md compares them):
///  * NonStandard (default): level by level, one 1D step along x, y and z of the current
///    low-pass block, then recurse on its low-pass octant (Stollnitz et al.'s non-standard
///    decomposition; basis functions have cubic support). Fewer coefficients for the 1%
///    error target (25% fewer for a light inside the grid, equal for smooth fields) and
///    about half the arithmetic of the standard one.
///  * Standard: the full 1D transform along x of every row, then y, then z (tensor product
///    basis). Fewer coefficients at very tight errors (0.1%).
enum class Decomposition : std::uint32_t { Standard = 0, NonStandard = 1 };

/// Orthonormal 3D Haar transform of a dense grid (x fastest), any size per axis (1 included).
///
/// 1D scheme (docs/basis.md): the transform on length n works level by level on the m
/// current approximations: pair (2i, 2i+1) becomes (a, d) = (c x0 + s x1, s x0 - c x1);
/// with m odd the last element is passed through to the next level unchanged.
/// Approximations go to [0, ceil(m/2)), details to [ceil(m/2), m); the next level transforms
/// [0, ceil(m/2)) until one element is left. (c, s) = (sqrt(w0/(w0+w1)), sqrt(w1/(w0+w1)))
/// where w0, w1 count the samples each input node stands for ("unbalanced Haar"): 1/sqrt(2)
/// for every pair except, on lengths that are not powers of two, the last pair of some
/// levels. Each step is a rotation, so the transform is orthonormal (Parseval holds
/// exactly), the scaling coefficient 0 is sum(x)/sqrt(n) and every other basis function has
/// zero mean: a constant field is one coefficient on any length (with the plain 1/sqrt 2
/// pass-through it would not be). On powers of two it is the textbook orthonormal Haar.
/// Coefficient layout: per axis as above, index i + nx (j + ny k); in both decompositions
/// coefficient 0 is the scaled mean.
///
/// Arithmetic (how float32 stays accurate): a literal implementation multiplies by
/// float(1/sqrt 2) at every level, and that constant is 1.7e-8 too small, a bias that grows
/// with the number of levels (3.4e-7 after the 18 levels of a 33^3 inverse). Instead the
/// inverse is computed as U P: P scales each coefficient once by k^e (k = 1/sqrt 2, e
/// fixed per coefficient position; exact when e is even), then U runs the levels with plain
/// sums and differences; only the last pair of a level of even length has a general 2x2
/// step (absorbing the unbalanced weights and the pass-through scales). Since U P is
/// orthogonal, the forward transform is P U^T with the same constants.
///
/// A transform object owns its plan and scratch memory: forward()/inverse() do not
/// allocate. One object per thread (calls mutate the scratch).
template <class T>
class HaarTransform {
public:
    explicit HaarTransform(core::Int3 dims, Decomposition d = Decomposition::NonStandard);

    const core::Int3& dims() const noexcept { return dims_; }
    Decomposition decomposition() const noexcept { return decomposition_; }
    std::size_t size() const noexcept { return dims_.volume(); }

    /// Samples -> coefficients, in place. data.size() must equal size().
    void forward(std::span<T> data);
    /// Coefficients -> samples, in place. data.size() must equal size().
    void inverse(std::span<T> data);

    /// One level of the 1D plan (see the scheme above).
    struct Level {
        int m = 0;      ///< length transformed at this level
        int pairs = 0;  ///< floor(m/2)
        int half = 0;   ///< ceil(m/2): approximations that go on to the next level
        /// When m is even, the last pair's step: x0 = u00 a + u01 d, x1 = u10 a + u11 d.
        T u00 = T(1), u01 = T(1), u10 = T(1), u11 = T(-1);
    };
    struct Axis {
        std::vector<Level> levels;      ///< finest first; J = levels.size()
        std::vector<int> t;             ///< t[l]: factor exponent of the last node entering level l (t[0] = 0)
        std::vector<int> detail_level;  ///< per position: the level whose detail it is (INT_MAX for 0)
        std::vector<int> exponent;      ///< standard decomposition: e of k^e in P per position
        /// Runs of equal exponent along the axis: [begin, end) and e.
        std::vector<int> run_begin, run_end, run_exponent;
    };

private:
    void scale(T* d) const noexcept;

    core::Int3 dims_;
    Decomposition decomposition_;
    Axis axes_[3];
    std::vector<T> powk_;    ///< k^e, e = 0 .. sum of the axes' depths
    std::vector<T> factor_;  ///< non-standard: P per coefficient
    std::vector<T> scratch_;
};

extern template class HaarTransform<float>;
extern template class HaarTransform<double>;

// =======================================================================================
// Float16

/// IEEE 754 binary16 from binary32, round to nearest, ties to even; subnormal halves are
/// produced (gradual underflow), magnitudes below half the smallest subnormal become +-0,
/// overflow gives +-infinity, NaN gives a quiet NaN with the sign kept.
std::uint16_t float_to_half(float f) noexcept;
/// Exact binary16 -> binary32 (every half is representable).
float half_to_float(std::uint16_t h) noexcept;

// =======================================================================================
// Compression (paper section 6)

enum class ThresholdMode : std::uint32_t {
    Absolute = 0,    ///< paper: drop |B| <= xi (units of the stored quantity)
    RelativeL2 = 1,  ///< drop |B| <= xi * ||B||_2 (the basis' own L2 norm): scale-free paper form
    Energy = 2,      ///< keep the fewest largest coefficients holding >= xi of ||B||^2, xi in [0, 1]
                     ///< (relative L2 error of the basis <= sqrt(1 - xi))
};
enum class Precision : std::uint32_t {
    Float32 = 0,
    Float16 = 1,  ///< binary16 with a per-basis power-of-two scale (docs/fgb-format.md)
};

/// How a .fgb block stores its kept coefficients (docs/fgb-format.md, "Block").
enum class Entropy : std::uint32_t {
    None = 0,     ///< fixed-width indices and values in magnitude order (fast to read)
    Deflate = 1,  ///< indices sorted and gap-coded (LEB128), values split into byte planes, the
                  ///< whole stream deflated (zlib): ~1.8x smaller for the same coefficients
};

/// "absolute" / "relative_l2" / "energy", "float32" / "float16", "standard" / "nonstandard",
/// "none" / "deflate" (the names used in scene files and reports).
std::string_view to_string(ThresholdMode m) noexcept;
std::string_view to_string(Precision p) noexcept;
std::string_view to_string(Decomposition d) noexcept;
std::string_view to_string(Entropy e) noexcept;

struct CompressionParams {
    ThresholdMode mode = ThresholdMode::Energy;
    double xi = 0.9999;  ///< energy kept: relative L2 error <= 1% per basis
    Precision precision = Precision::Float16;
    Decomposition decomposition = Decomposition::NonStandard;
    Entropy entropy = Entropy::Deflate;  ///< file encoding only: lossless, the values are the same
    bool operator==(const CompressionParams&) const = default;
};

/// Checks xi against the mode (finite, >= 0; <= 1 for Energy); throws core::Error naming
/// `where`.xi.
void validate(const CompressionParams& p, std::string_view where);

/// The kept coefficients of one basis (one light, one direction), in canonical order:
/// decreasing magnitude of the stored (rounded) value, ties by increasing index. Because of
/// that order, any prefix is the same basis compressed at a stricter threshold (see
/// retruncate()); and because it depends only on the stored values, a reader that gets the
/// coefficients in another order (Entropy::Deflate stores them by index) restores it exactly.
struct CompressedBasis {
    std::vector<std::uint32_t> index;  ///< position in the Haar coefficient array (x fastest)
    std::vector<float> value;          ///< the stored value (already rounded to the precision)
    double gamma = 0.0;                ///< paper's gamma: sqrt(sum of squares of the dropped coefficients)
    double norm = 0.0;                 ///< ||B||_2 of all coefficients before thresholding (= ||b||_2)
    int scale_exp = 0;                 ///< float16 only: value = half * 2^scale_exp; 0 for float32

    std::size_t size() const noexcept { return index.size(); }
    bool operator==(const CompressedBasis&) const = default;
};

/// All bases of one virtual light (every output direction, for every stored component;
/// FgbMetadata::basis_index gives the order): the unit of a bake job and of a file block.
struct CompressedLight {
    std::uint32_t light = 0;
    std::vector<CompressedBasis> directions;  ///< FgbMetadata::bases() entries
    std::size_t coefficient_count() const noexcept;
    bool operator==(const CompressedLight&) const = default;
};

/// Thresholds one basis given in the Haar domain (any length <= 2^32). Sums in double.
/// Values are rounded to the storage precision here, so the result is exactly what a file
/// stores. Throws core::Error (naming `where`) for non-finite coefficients or values that
/// overflow the precision.
CompressedBasis compress_coefficients(std::span<const double> coefficients, const CompressionParams& p,
                                      std::string_view where = "compress");

/// Forward Haar (in double) and compression of every direction of one light's field.
/// `plan` must have the field's dims and the params' decomposition. Throws core::Error for
/// non-finite samples.
CompressedLight compress_light(std::uint32_t light, const transport::SourceField& field, const CompressionParams& p,
                               HaarTransform<double>& plan);

/// Applies a stricter threshold to a stored basis without the original data: keeps the
/// leading coefficients that pass it (magnitude order makes this a prefix) and adds the
/// dropped ones to gamma. A looser threshold than the stored one changes nothing.
void retruncate(CompressedBasis& b, ThresholdMode mode, double xi);

/// Adds weight * B into a dense coefficient array (size = cells): the run time's Eq. 9.
void accumulate(const CompressedBasis& b, float weight, std::span<float> coefficients);
void accumulate(const CompressedBasis& b, double weight, std::span<double> coefficients);

/// The paper's ambient term (Eq. 10) needs care with an orthonormal transform: gamma is
/// the L2 norm of the reconstruction error over all N cells (Parseval), so the per-cell RMS
/// error is gamma / sqrt(N); and while coefficient 0 (the scaled mean, among the largest of
/// a non-negative basis) is kept, the error has zero mean — the best constant correction
/// is 0 (were it dropped, it would be c0 / sqrt(N)). Adding e_l * gamma to every cell (Eq. 10
/// literally) adds sqrt(N) times the RMS error as a bias. The run time should add no
/// ambient by default; where a visual floor is wanted, this per-cell value (same energy as
/// the dropped detail) is the consistent one. docs/basis.md has the argument.
inline double ambient_rms(const CompressedBasis& b, std::size_t cells) noexcept {
    return cells ? b.gamma / std::sqrt(double(cells)) : 0.0;
}

// =======================================================================================
// The .fgb file (docs/fgb-format.md)

inline constexpr std::uint32_t kFgbVersion = 3;
/// Largest lighting grid a .fgb may describe (2^26 cells = 256 MiB per float32 field):
/// loaders and the run time allocate per-cell arrays from it, so it is bounded by the format.
inline constexpr std::size_t kMaxFgbCells = std::size_t(1) << 26;

/// What the file was baked from: a 64-bit hash of every bake-relevant scene parameter and
/// the canonical description it was computed from (one "key=value" per line), both stored
/// so that a stale file is detected *and* explained (the first differing line is named).
struct BakeKey {
    std::uint64_t hash = 0;
    std::string description;
    /// hash = hash_description(description).
    static BakeKey from_description(std::string description);
    bool operator==(const BakeKey&) const = default;
};

/// 64-bit FNV-1a of the bytes, finished with the SplitMix64 mixer.
std::uint64_t hash_description(std::string_view text) noexcept;

/// Everything in a .fgb file besides the per-light blocks.
struct FgbMetadata {
    BakeKey key;
    core::GridGeometry lighting;         ///< the grid the bases live on
    std::vector<glm::dvec3> directions;  ///< output directions s_m (unit vectors), 1..64
    /// What the bases hold, a mask of kContentSingle (order 1, the direct term) and
    /// kContentMultiple (orders >= 2). With components == 1 each (light, direction) has one
    /// basis holding the sum of the content; with components == 2 (content must be both)
    /// the single and the multiple part are stored as separate bases, so the run time can
    /// show either (both are linear: summing them into one accumulator costs no extra
    /// inverse transform).
    std::uint32_t content = kContentSingle | kContentMultiple;
    std::uint32_t components = 1;  ///< 1 or 2 (see content)
    VirtualLightGrid lights;
    CompressionParams compression;
    bool operator==(const FgbMetadata&) const = default;

    static constexpr std::uint32_t kContentSingle = 1, kContentMultiple = 2;
    /// Bases per light: components * directions.size(). CompressedLight::directions holds
    /// them in the order basis_index(c, m) = c * directions.size() + m.
    std::size_t bases() const noexcept { return std::size_t(components) * directions.size(); }
    std::size_t basis_index(std::size_t component, std::size_t direction) const noexcept {
        return component * directions.size() + direction;
    }
    std::size_t light_count() const noexcept { return lights.count(); }
    std::size_t cells() const noexcept { return lighting.cell_count(); }
    /// Bytes per stored coefficient index: 2 when cells <= 65536, else 4.
    int index_bytes() const noexcept { return cells() <= 65536 ? 2 : 4; }
};

/// Checks a metadata record (geometry, unit directions, ascending finite light coordinates,
/// light count, compression params); throws core::Error naming `where`.
void validate(const FgbMetadata& m, std::string_view where);

/// One light's block exactly as stored (bytes), with its CRC32.
struct EncodedBlock {
    std::uint32_t light = 0;
    std::uint32_t crc = 0;
    std::vector<std::uint8_t> bytes;
};

/// Encodes a light for a file with metadata `m` (directions, precision, index width must
/// match; FULGUR_ASSERT on misuse such as a wrong direction count).
EncodedBlock encode_block(const CompressedLight& light, const FgbMetadata& m);

/// Writes a .fgb for lights [light_begin, light_end) of the metadata's light grid: the
/// whole grid (a complete file) or a part of it (a partial file, the output of one bake
/// job). Blocks may be added in any order and from several threads; each light exactly
/// once. The file is streamed to "<path>.tmp" and renamed to `path` by finish(), so a
/// crashed job never leaves a file that looks valid. Destroying an unfinished writer
/// removes the temporary file.
class FgbWriter {
public:
    FgbWriter(std::filesystem::path path, FgbMetadata meta, std::uint32_t light_begin, std::uint32_t light_end);
    FgbWriter(std::filesystem::path path, FgbMetadata meta);  ///< all lights
    ~FgbWriter();
    FgbWriter(const FgbWriter&) = delete;
    FgbWriter& operator=(const FgbWriter&) = delete;

    void add(const CompressedLight& light);
    void add(const EncodedBlock& block);
    /// Throws core::Error if a light of the range is missing; writes index and header.
    void finish();

    const FgbMetadata& metadata() const noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Reads and checks a .fgb: the constructor validates the fixed header, the header CRC
/// (which covers metadata and index), the metadata and the index (offsets inside the file,
/// blocks disjoint). read_light() validates a block's CRC and contents. Every error is a
/// core::Error whose where() names the file, the byte offset and the field or light.
/// Never reads outside the file and never allocates from a size it has not bounded by the
/// file size.
class FgbReader {
public:
    explicit FgbReader(const std::filesystem::path& path);
    /// Reads from memory; `name` stands for the file name in messages.
    FgbReader(std::vector<std::uint8_t> bytes, std::string name);
    ~FgbReader();
    FgbReader(FgbReader&&) noexcept;
    FgbReader& operator=(FgbReader&&) noexcept;

    const FgbMetadata& metadata() const noexcept;
    std::uint32_t light_begin() const noexcept;
    std::uint32_t light_end() const noexcept;
    bool partial() const noexcept;
    std::uint64_t file_size() const noexcept;
    const std::string& name() const noexcept;

    /// Throws core::Error "stale bake" unless the file's key equals `expected`; the message
    /// names both hashes and the first differing description line.
    void check_key(const BakeKey& expected) const;

    /// Order of the coefficients read_light() returns within each basis.
    enum class Order {
        Canonical,  ///< CompressedBasis' order (decreasing magnitude): what retruncate() needs
        Any,        ///< as stored (by index for Entropy::Deflate): skips a sort, for consumers
                    ///< such as the run time's accumulation that do not care
    };
    /// Decodes and validates light l (light_begin() <= l < light_end()).
    CompressedLight read_light(std::uint32_t l, Order order = Order::Canonical);
    /// Total coefficients stored in light l's block, from its table (CRC-checked, each count
    /// <= cells): sizes a consumer's arrays before decoding anything.
    std::uint64_t coefficient_count(std::uint32_t l);
    /// The block's bytes after checking its CRC and contents (for merging).
    EncodedBlock read_encoded(std::uint32_t l);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// A complete bake in memory: lights[l].light == l for every light of the grid.
struct BakedBasis {
    FgbMetadata meta;
    std::vector<CompressedLight> lights;
    std::size_t coefficient_count() const noexcept;
};

struct LoadOptions {
    const BakeKey* expected_key = nullptr;  ///< when set, a stale file is rejected
    /// Optional stricter threshold applied at load (progressive truncation, retruncate()).
    bool retruncate = false;
    ThresholdMode retruncate_mode = ThresholdMode::Energy;
    double retruncate_xi = 1.0;
};

/// Loads a complete .fgb (a partial file is rejected), validating every block.
BakedBasis load_fgb(const std::filesystem::path& path, const LoadOptions& options = {});
BakedBasis load_fgb(FgbReader& reader, const LoadOptions& options = {});

/// Joins partial files of one bake into `out`: the metadata must be byte-identical, the
/// light ranges disjoint and contiguous; every block's CRC and contents are checked and
/// the bytes copied unchanged. The result is complete when the ranges cover every light.
void merge_fgb(const std::filesystem::path& out, std::span<const std::filesystem::path> parts);

// =======================================================================================
// Reconstruction and export (NRRD float32, opens in ParaView / 3D Slicer)

struct WeightedLight {
    std::uint32_t light = 0;
    double weight = 1.0;
};

/// sum_l w_l b_l for direction m from the compressed data: the coefficients are summed
/// (Eq. 9) over the lights and over the stored components (the total S the file holds)
/// and inverse transformed once (the bake's decomposition), in double; no ambient term is
/// added.
core::Grid3<float> reconstruct(const BakedBasis& baked, std::span<const WeightedLight> lights, std::size_t direction);

/// sum_l w_l b_l for direction m from uncompressed fields: field_of(light) returns that
/// light's SourceField (all must share the geometry and direction count).
core::Grid3<float> weighted_sum(std::span<const WeightedLight> lights, std::size_t direction,
                                const std::function<const transport::SourceField&(std::uint32_t)>& field_of);

/// Writes reconstruct(...) / weighted_sum(...) as NRRD with a content line naming the
/// lights, weights and direction.
void export_compressed_nrrd(const std::filesystem::path& path, const BakedBasis& baked,
                            std::span<const WeightedLight> lights, std::size_t direction);
void export_raw_nrrd(const std::filesystem::path& path, std::span<const WeightedLight> lights, std::size_t direction,
                     const std::function<const transport::SourceField&(std::uint32_t)>& field_of);

}  // namespace fulgur::basis
