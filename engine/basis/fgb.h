// fulgur::basis — the .fgb baked file (docs/fgb-format.md specifies it byte by byte): its
// metadata, per-light blocks, a writer for whole or partial files, a validating reader and
// the merge of partial files. A bake is a list of per-light jobs, each writing its range of
// lights, then merge_fgb() (docs/design.md#scaling-past-one-machine).
#pragma once

#include "basis/compression.h"
#include "basis/virtual_lights.h"
#include "core/core.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fulgur::basis {

inline constexpr std::uint32_t kFgbVersion = 3;
/// Largest lighting grid a .fgb may describe (2^26 cells = 256 MiB per float32 field):
/// loaders and the run time allocate per-cell arrays from it, so it is bounded by the format.
inline constexpr std::size_t kMaxFgbCells = std::size_t(1) << 26;
/// Largest .fgb file opened (256 GiB, far above any bake one machine writes): the reader
/// allocates only what it has bounded by the file size, so this is a sanity bound on input.
inline constexpr std::uint64_t kMaxFgbBytes = std::uint64_t(1) << 38;
/// Largest coefficient magnitude a .fgb may hold, 2^64 per unit light intensity: the run time
/// multiplies bases by weights up to the brightest bolt (1e12 W/sr, about 2^40) and sums lights
/// and Haar levels in float32 (at most 2^128), so larger values would turn to Inf once lit.
/// (A physical basis is many orders below it.) Float16 blocks: scale_exp <= 64 - 16 = 48.
inline constexpr int kMaxLitExponent = 64;

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

/// Why two keys differ, for a "stale" message: "first difference at line N: the file has
/// "a=1", the scene has "a=2"" (or that only the hashes differ). Empty when they are equal.
std::string key_difference(const BakeKey& file, const BakeKey& expected);

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
/// once. The file is streamed to a temporary beside it and renamed to `path` by finish()
/// (core::AtomicFile: locked against other writers of `path`, checked writes, temporary
/// removed on exceptions and signals), so a crashed job never leaves a file that looks
/// valid. Destroying an unfinished writer removes the temporary file.
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
    /// check_key, then the file's geometry against what the scene's plan expects: lighting
    /// grid (dims, voxel size, origin), output directions, content and components, the
    /// virtual-light grid and the compression settings. A header edited consistently (its
    /// checksums recomputed) with the key left alone is refused here, naming the field.
    void check_metadata(const FgbMetadata& expected) const;

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

}  // namespace fulgur::basis
