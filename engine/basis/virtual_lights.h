// fulgur::basis — the virtual-light grid (Dobashi et al. 2007, section 5): where the unit
// point lights whose bases are baked sit. docs/basis.md section 1 gives the construction.
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <string_view>
#include <vector>

namespace fulgur::basis {

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

/// Builds the virtual-light grid for a cloud (the voxels denser than
/// p.density_threshold): x and y nodes exactly h_usr apart over the footprint widened by
/// p.margin; z nodes h_usr apart from the cloud base through the top, and below the base
/// as Eq. 4 allows down to ground_height (docs/basis.md section 1).
/// Errors (core::Error): an empty cloud, a cloud base below ground_height, invalid
/// parameters, more than kMaxVirtualLights lights.
VirtualLightGrid build_virtual_light_grid(const core::Grid3<float>& density, const VirtualLightParams& p);

}  // namespace fulgur::basis
