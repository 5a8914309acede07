// fulgur::runtime — a strike's own light in place of the bases' for the frames before its first
// Monte Carlo estimate: its single scattering by rays cast from its points, its multiple
// scattering by flux-limited diffusion through the cloud's own density (transport/diffusion.h).
//
// The bases carry a strike's light as the splat onto virtual lights 1500 m apart represents it;
// next to the channel, and where the cloud's base and edges cut the light off, the splat cannot
// (docs/presets.md). Per strike and glow group this casts rays from the points through the
// lighting grid (their single scattering and first-scattered emission a sigma_t phi1), solves
// the diffusion of that emission, and takes the diffused light's source function as an HG lobe
// along its flux. Added to a NearFieldParts as a correction (the cast and the solve minus the
// bases' parts of the same points), so that the bases' frame plus the correction shows the
// strike's own light. On the default storm's strikes this takes the first lit frame from 35.5%
// (NearField's kernel) to 23.2% worst, its median from 31.3% to 17.4%, against the truth
// (docs/presets.md, "A strike's multiple scattering by diffusion").
#pragma once

#include "runtime/baked_bases.h"
#include "runtime/near_field.h"
#include "transport/diffusion.h"

#include <cstdint>
#include <memory>
#include <span>

namespace fulgur::runtime {

struct StrikeDiffusionOptions {
    /// Rays cast from each point for its first-scattered emission: 32 and 128 give the same
    /// figures on the default storm (the diffusion smooths what 32 rays sample).
    int rays = 32;
    /// Also the points' single scattering by the same rays, through the whole grid, in place of
    /// the bases' (and of NearField's correction of it): on the default storm's strikes 11-26%
    /// single against the bases with NearField's 14-33%, the first frame's worst 24.5% against
    /// 28.1% (docs/presets.md).
    bool single = true;
    transport::DiffusionOptions diffusion;
    std::uint64_t seed = 1;  ///< turns each point's rays (transport::add_first_scattered_emission)
};

class StrikeDiffusion {
public:
    /// Keeps a copy of the lighting medium; `bases` must outlive this. `directions`: the output
    /// directions, the order of the parts' [m][cell] layout. Asserts rays in [1, 65536].
    StrikeDiffusion(const transport::LightingMedium& lighting, const BakedBases& bases,
                    std::span<const glm::dvec3> directions, const StrikeDiffusionOptions& options = {});
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
