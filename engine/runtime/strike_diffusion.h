// fulgur::runtime — a strike's own light in place of the bases' for the frames before its first
// Monte Carlo estimate: its single scattering by rays cast from its points, its multiple
// scattering by flux-limited diffusion through the cloud's own density (transport/diffusion.h).
//
// The bases carry a strike's light as the splat onto virtual lights 1500 m apart represents it;
// next to the channel, and where the cloud's base and edges cut the light off, the splat cannot
// (docs/presets.md). Per strike and glow group this casts rays from the points through the
// cloud's full-resolution density (or the lighting grid's) for their single scattering and
// first-scattered emission a sigma_t phi1 on the lighting grid, solves the diffusion of that
// emission, and takes the diffused light's source function as an HG lobe along its flux. Added
// to a NearFieldParts as a correction (the cast and the solve minus the bases' parts of the same
// points), so that the bases' frame plus the correction shows the strike's own light. On the
// default storm's strikes the first lit frame is 18.6% worst against the truth (NearField's
// kernel: 35.5%; the same with the cast through the lighting grid: 23.2%) (docs/presets.md, "A
// strike's multiple scattering by diffusion").
#pragma once

#include "runtime/baked_bases.h"
#include "runtime/near_field.h"
#include "transport/diffusion.h"

#include <cstdint>
#include <memory>
#include <span>

namespace fulgur::runtime {

struct StrikeDiffusionOptions {
    /// Rays cast from each point through the lighting grid, for the first-scattered emission
    /// (and the single scattering) when the full-resolution cast is not used: 32 and 128 give
    /// the same multiple part on the default storm (the diffusion smooths what 32 rays sample).
    int rays = 32;
    /// Also the points' single scattering by rays, through the whole grid, in place of the
    /// bases' (and of NearField's correction of it): through the lighting grid, on the default
    /// storm's strikes 11-26% single against the bases with NearField's 14-33%, the first
    /// frame's worst 24.5% against 28.1% (docs/presets.md).
    bool single = true;
    /// With the cloud's full-resolution density given to the constructor: rays per point of the
    /// single scattering marched through it (transport::add_point_scattering_fine) in place of
    /// the lighting grid's cast; 2.7-8.9% single on the default storm's strikes at 128 rays, 4-21%
    /// at 32, where the lighting grid's cast stays at 4-21% with any number. 0: the lighting
    /// grid's cast of `rays`.
    int fine_rays = 128;
    /// The diffusion's first-scattered emission from the full-resolution cast too (one cast),
    /// else from the lighting grid's cast of `rays`: the storm's worst first frame 19.1% against
    /// 19.3% (docs/presets.md).
    bool fine_emission = true;
    transport::DiffusionOptions diffusion;
    std::uint64_t seed = 1;  ///< turns each point's rays (transport::add_first_scattered_emission)
};

class StrikeDiffusion {
public:
    /// Keeps a copy of the lighting medium; `bases` and `full` (the cloud's full-resolution
    /// density with the same optics, or null: the lighting grid's alone) must outlive this.
    /// `directions`: the output directions, the order of the parts' [m][cell] layout. Asserts
    /// rays and fine_rays in range.
    StrikeDiffusion(const transport::LightingMedium& lighting, const BakedBases& bases,
                    std::span<const glm::dvec3> directions, const StrikeDiffusionOptions& options = {},
                    const transport::LightingMedium* full = nullptr);
    ~StrikeDiffusion();
    StrikeDiffusion(const StrikeDiffusion&) = delete;
    StrikeDiffusion& operator=(const StrikeDiffusion&) = delete;

    /// Whether the bases hold the multiple part apart from the single, or none of it (a
    /// one-component bake with both cannot: then add() adds nothing and the caller keeps
    /// NearField's own multiple model), on this lighting grid and direction set.
    bool separable() const noexcept;

    /// Whether add() replaces the single part too (options.single).
    bool replaces_single() const noexcept;

    /// Adds to out.multiple ([m][cell]; both parts sized here when `out` is empty) the diffusion
    /// solve's multiple scattering of `sources` minus the bases' multiple part of their splat;
    /// with options.single, to out.single the cast's single scattering minus the bases' single
    /// part (then `out` should hold no NearField correction).
    /// Sources with a non-finite position or intensity, or none, add nothing. Thread-safe.
    /// Returns false when nothing was added (nothing lit, or not separable()).
    bool add(std::span<const transport::PointSource> sources, NearFieldParts& out) const;

    /// The last add()'s diffusion work: conjugate-gradient iterations and whether every solve
    /// converged (for benchmarks and studies; not synchronized).
    int last_iterations() const noexcept;
    bool last_converged() const noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::runtime
