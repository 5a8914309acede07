// fulgur::runtime — the splat's near-field correction: what trilinear splatting onto virtual
// lights a spacing apart cannot represent next to a channel, added per strike from a local
// model, as particle-particle particle-mesh methods split a force:
//   S ~ sum_l e_l B_l + sum_q K[q] - sum_l e_l K[l],
// with K a point's model on the lighting voxels within `reach` of it (ramped to zero over the
// last voxel). Beyond a few voxels the two sums cancel, since the trilinear weights keep each
// source's position, so the bases keep the far field; next to the channel the model replaces
// the splat's. The model (docs/presets.md, "A near-field correction of the splat", measures it
// and the alternatives):
//   single scattering: a I p(cos) T / r^2 per output direction through the lighting grid's
//     density;
//   multiple scattering: that single scattering's scalar first-scattered source spread over the
//     voxels around it by diffusion's Green's function, the same in every direction.
// Both by rays cast from the point, whose r^2 dr dOmega cancels the 1/r^2 of a point inside a
// voxel. A light's own model does not depend on the strike: it is made once per light, on first
// use, and kept.
#pragma once

#include "basis/virtual_lights.h"
#include "lightning/lightning.h"
#include "transport/sources.h"
#include "transport/transport.h"

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace fulgur::runtime {

struct NearFieldOptions {
    /// Rays cast from each point (Fibonacci sphere): the knob that trades accuracy for time.
    /// On the default storm's worst strike 32 rays give 35.4% against the truth, 128 rays the
    /// same, the splat alone 75.7% (docs/presets.md).
    int rays = 32;
    /// The model's support, in lighting voxels (4: 3 km on the default storm; 6 changed no
    /// figure by more than 0.001).
    double reach_voxels = 4.0;
    /// Whether the correction carries its multiple-scattering model; false: single scattering
    /// alone (another model, runtime::StrikeDiffusion, replaces the bases' multiple part).
    bool multiple = true;
};

/// A correction's two parts on the lighting grid, single and multiple scattering, each [m][cell]
/// (every output direction; NearField's multiple model is the same in every direction,
/// StrikeDiffusion's is not). Empty: nothing to add.
struct NearFieldParts {
    std::vector<float> single, multiple;
    bool empty() const noexcept { return single.empty(); }
};

/// The sources a correction takes: finite position and a finite, non-zero intensity.
std::vector<transport::PointSource> lit_sources(std::span<const transport::PointSource> sources);

class NearField {
public:
    /// Keeps a copy of the lighting medium and the light grid. `directions`: S's output
    /// directions, the order of every field's [m][cell] layout. Asserts rays in [1, 65536] and
    /// reach_voxels in [1, 64].
    NearField(const transport::LightingMedium& lighting, const basis::VirtualLightGrid& lights,
              std::span<const glm::dvec3> directions, const NearFieldOptions& options = {});
    ~NearField();
    NearField(const NearField&) = delete;
    NearField& operator=(const NearField&) = delete;

    /// Adds the correction of `sources` (the points the splat takes, at their intensities) to
    /// `out` (sized here when empty and there is something to add). Sources with a non-finite
    /// position or intensity, or none, add nothing. Thread-safe.
    void add(std::span<const transport::PointSource> sources, NearFieldParts& out) const;

    /// The correction of a bolt's strokes at unit glow, one group ([0] the main channel, [1]
    /// the branches; lightning::lit_segments), cut into points as a frame's splat cuts them
    /// (Splatter::source_spacing); empty when the group lights nothing.
    NearFieldParts strokes(const lightning::Bolt& bolt, std::size_t group) const;
    /// The points strokes() takes for that group.
    std::vector<transport::PointSource> stroke_sources(const lightning::Bolt& bolt, std::size_t group) const;

    /// Makes light l's model now if it is not kept yet (idle time: a strike's first correction
    /// then pays only for its own points). Thread-safe.
    void keep_light(std::size_t l) const;
    /// Lights whose model has been made so far.
    std::size_t kept_lights() const;
    std::size_t light_count() const noexcept;
    std::size_t cells() const noexcept;
    std::size_t directions() const noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::runtime
