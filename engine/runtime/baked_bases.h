// fulgur::runtime — the baked bases in memory, in the layout the per-frame accumulation reads.
#pragma once

#include "basis/basis.h"
#include "core/core.h"

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

namespace fulgur::runtime {

/// The baked bases in a layout for fast accumulation (loaded from a .fgb; validated).
/// Layout (docs/runtime.md): one pool of coefficients, per (light, basis) a contiguous run
/// [offset, next offset) of indices (uint16 when the lighting grid has <= 65536 cells, else
/// uint32) and float32 values (float16 files are expanded at load), in the file's order.
class BakedBases {
public:
    /// Loads and validates `fgb` (basis::load_fgb: every CRC, index and value). With the
    /// scene's key (bake::scene_key), a file baked from other parameters is rejected before
    /// its blocks are read: core::Error "stale bake" naming both hashes and the first scene
    /// parameter that changed (basis::FgbReader::check_key).
    static BakedBases load(const std::filesystem::path& fgb, const std::optional<basis::BakeKey>& expected = {});
    /// The same, checking the file's whole header against the scene's plan
    /// (basis::FgbReader::check_metadata: key, grids, directions, lights, compression).
    static BakedBases load(const std::filesystem::path& fgb, const basis::FgbMetadata& expected);

    const core::GridGeometry& lighting() const noexcept;
    const std::vector<glm::dvec3>& directions() const noexcept;
    const basis::VirtualLightGrid& lights() const noexcept;
    const basis::FgbMetadata& metadata() const noexcept;
    bool has_multiple() const noexcept;  ///< the multiple-scattering component was baked
    /// Single and multiple scattering are stored as separate bases (FgbMetadata::components
    /// == 2), so a reconstruction can show either alone.
    bool separate() const noexcept;
    std::size_t coefficient_count() const noexcept;  ///< all kept coefficients, all components
    std::size_t memory_bytes() const noexcept;       ///< bytes of the coefficient pool and offsets

    BakedBases(BakedBases&&) noexcept;
    BakedBases& operator=(BakedBases&&) noexcept;
    ~BakedBases();
    /// The storage (detail/internal.h), for the module's own reconstruction and tests.
    struct Impl;

private:
    friend const Impl& bases_impl(const BakedBases& b) noexcept;
    explicit BakedBases(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::runtime
