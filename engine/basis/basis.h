// fulgur::basis — virtual lights, basis intensities and their compressed storage
// (Dobashi et al. 2007, sections 5 and 6): the virtual-light grid, the 3D Haar transform,
// thresholding, and the .fgb baked file.
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <vector>

namespace fulgur::basis {

/// Spacing of the virtual-light grid (paper section 5).
struct VirtualLightParams {
    double h_usr = 400.0;      ///< base interval (m): horizontal spacing, and vertical above the cloud base
    double epsilon = 1e-8;     ///< Eq. 4 bound on 1/r_l^2 - 1/r_{l+1}^2 below the base (1/m^2)
    double margin = 400.0;     ///< horizontal margin around the cloud's footprint (m)
    double ground_height = 0.0;  ///< lowest layer of virtual lights (m)
};

/// The non-uniform (rectilinear) virtual-light grid: node coordinates per axis, ascending.
/// Light l = i + nx * (j + ny * k) sits at (x[i], y[j], z[k]).
struct VirtualLightGrid {
    std::vector<double> x, y, z;

    std::size_t count() const noexcept { return x.size() * y.size() * z.size(); }
    std::size_t index(std::size_t i, std::size_t j, std::size_t k) const noexcept {
        return i + x.size() * (j + y.size() * k);
    }
    glm::dvec3 position(std::size_t l) const noexcept {
        const std::size_t nx = x.size(), ny = y.size();
        return {x[l % nx], y[(l / nx) % ny], z[l / (nx * ny)]};
    }
};

}  // namespace fulgur::basis
