// fulgur::cloud — sub-voxel detail: billows finer than the density voxels, carved into the
// cloud's edges by erosion with a tileable noise (as Schneider's Nubis does for Horizon's
// clouds), deterministic per seed.
//
// The detailed density at a point p is
//   rho_d(p) = erode(rho(p), b(p), strength),   erode(rho, b, s) = max(rho - lo, 0) / (1 - lo),
//   lo = s (1 - b),
// with rho the trilinear interpolant of the density voxels and b(p) in [0, 1] the billow
// field: octaves of inverted cellular (Worley) noise, the largest billows `scale` metres
// across and each octave half the size of the last, tiled with period 2 scale. Erosion only
// removes density (rho_d <= rho): where the cloud is dense (rho = 1) nothing changes, at its
// thin edges the gaps between billows empty out. So a majorant of rho is one of rho_d, and
// the empty-space distance of the undetailed cloud stays valid for the detailed one.
//
// Where the detail is used:
//   * the ray march evaluates rho_d at every sample (render: the noise tile as a texture,
//     the same tile and the same erosion as here);
//   * the solvers (bake, truth, sun and sky) integrate the full-resolution density grid;
//     detailed_density() gives them each voxel's mean of rho_d over its box, so the light
//     they compute sees the detail's extinction at the grid's resolution. Structure finer
//     than a voxel shapes what the camera sees, not the light transport (docs/cloud.md,
//     "Sub-voxel detail", measures what that leaves out).
//   * an outside renderer (fulgur-shot --blender) gets rho_d itself on a finer voxel grid
//     (detailed_on_finer_grid), so it renders the billows the march draws.
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <vector>

namespace fulgur::cloud {

/// The scene's "cloud.detail" object, by the same names.
struct SubvoxelDetail {
    std::uint64_t seed = 1;  ///< the billows' layout
    double scale = 400.0;    ///< metres across the largest billows (the first octave's cells)
    int octaves = 3;         ///< 1 to kMaxDetailOctaves; each halves the billow size
    double strength = 0.5;   ///< 0 (no erosion) to 1 (the thin edges between billows emptied)
};

inline constexpr int kMaxDetailOctaves = 4;
/// Texels along each axis of the billow tile (kDetailTile^3, one byte each).
inline constexpr int kDetailTile = 64;

/// Checks the parameters; throws core::Error whose where() is the scene field
/// ("cloud.detail.scale", ...).
void validate_subvoxel_detail(const SubvoxelDetail& d);

/// The billow field b in [0, 1] on one periodic tile of kDetailTile^3 texels (x fastest),
/// quantized to bytes (what the renderer uploads as an R8 texture with repeat wrapping and
/// linear filtering). sample() filters it exactly as that texture is filtered.
class DetailNoise {
public:
    explicit DetailNoise(const SubvoxelDetail& d);
    const SubvoxelDetail& params() const noexcept { return params_; }
    /// Tile period in metres (2 scale).
    double period() const noexcept { return 2.0 * params_.scale; }
    const std::vector<std::uint8_t>& texels() const noexcept { return texels_; }
    /// b at a world position (metres): trilinear over the periodic tile, texel centres at
    /// (i + 0.5) / kDetailTile of the period.
    float sample(const glm::dvec3& world) const noexcept;

private:
    SubvoxelDetail params_;
    std::vector<std::uint8_t> texels_;
};

/// Erosion of density rho by billow value b with the given strength (see the top of this
/// file); 0 <= result <= rho for rho in [0, 1]. Written as the shader writes it.
inline float erode(float rho, float b, float strength) noexcept {
    const float lo = strength * (1.0f - b);
    const float num = rho - lo > 0.0f ? rho - lo : 0.0f;
    const float den = 1.0f - lo > 1e-6f ? 1.0f - lo : 1e-6f;
    return num / den;
}

/// The detailed density at a world point: erode(density.sample(p), noise.sample(p)).
float detailed_at(const core::Grid3<float>& density, const DetailNoise& noise, const glm::dvec3& world) noexcept;

/// Supersamples per voxel axis of detailed_density() (4^3 per voxel).
inline constexpr int kDetailSupersamples = 4;

/// The density grid the solvers integrate: each voxel's value times the fraction of the
/// trilinear field's mass the erosion keeps over the voxel's box,
///   rho_d[v] = rho[v] * sum erode(rho(x), b(x)) / sum rho(x),
/// summed over kDetailSupersamples^3 stratified points x of the box. Empty voxels stay
/// exactly 0, rho_d <= rho, and with strength 0 the result equals the input bit for bit.
/// Deterministic whatever core::thread_count() is.
core::Grid3<float> detailed_density(const core::Grid3<float>& density, const DetailNoise& noise);

/// The detailed density rho_d (detailed_at) at the voxel centres of a grid over the same box
/// `refine` times finer than `density`'s (voxels voxel_size / refine across): the billows the
/// march draws, for a renderer that reads a voxel grid (fulgur-shot --blender). Voxels whose
/// point of `density` is 0 stay exactly 0. Deterministic whatever core::thread_count() is.
core::Grid3<float> detailed_on_finer_grid(const core::Grid3<float>& density, const DetailNoise& noise, int refine);

/// The refinement for detailed_on_finer_grid: the smallest whose voxels are at most half the
/// finest billow across (scale / 2^(octaves - 1) / 2; at most 64), lowered until the finer grid holds at most
/// `max_voxels` voxels; at least 1.
int detail_refinement(const core::GridGeometry& g, const SubvoxelDetail& d, std::uint64_t max_voxels) noexcept;

}  // namespace fulgur::cloud
