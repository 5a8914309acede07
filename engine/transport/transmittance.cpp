// Medium validation and transmittance by exact voxel traversal (detail/traversal.h): the
// helpers every solver shares (single scattering, Monte Carlo, lattice-Boltzmann).
#include "transport/detail/traversal.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <cmath>
#include <string>

namespace fulgur::transport {

void validate_medium(const LightingMedium& m) {
    core::validate_geometry(m.density.geom, "medium.density");
    if (m.density.data.size() != m.density.geom.cell_count())
        throw core::Error("medium.density", "has " + std::to_string(m.density.data.size()) + " values for " +
                                                std::to_string(m.density.geom.cell_count()) + " voxels");
    const Medium& o = m.optics;
    if (!std::isfinite(o.extinction) || o.extinction < 0.0)
        throw core::Error("medium.extinction",
                          "must be a finite value >= 0 (1/m), got " + std::to_string(o.extinction));
    if (!(o.albedo >= 0.0 && o.albedo <= 1.0))
        throw core::Error("medium.albedo", "must be in [0, 1], got " + std::to_string(o.albedo));
    if (!std::isfinite(o.g)) throw core::Error("medium.g", "must be finite (it is clamped to +-0.9999)");
    for (std::size_t c = 0; c < m.density.data.size(); ++c) {
        const float v = m.density.data[c];
        if (!(v >= 0.0f && v <= 1.0f)) {
            const core::Int3 ijk = m.density.geom.unindex(c);
            throw core::Error("medium.density[" + std::to_string(ijk.x) + "," + std::to_string(ijk.y) + "," +
                                  std::to_string(ijk.z) + "]",
                              "density must be in [0, 1], got " + std::to_string(v));
        }
    }
    if (m.phase_mix) validate_phase_mix(*m.phase_mix, m.density.geom);
    if (m.path_mix) validate_path_mix(*m.path_mix, m.density.geom);
}

namespace {

// Throws unless `share` lies on `geom` with every value in [0, 1]; `field` names it.
void validate_share(const core::Grid3<float>& share, const core::GridGeometry& geom, const std::string& field,
                    const std::string& grid_is) {
    if (!(share.geom == geom) || share.data.size() != geom.cell_count())
        throw core::Error(field, "must lie on " + grid_is + " (" + std::to_string(geom.dims.x) + "x" +
                                     std::to_string(geom.dims.y) + "x" + std::to_string(geom.dims.z) + " voxels)");
    for (std::size_t c = 0; c < share.data.size(); ++c) {
        const float v = share.data[c];
        if (!(v >= 0.0f && v <= 1.0f)) {
            const core::Int3 ijk = geom.unindex(c);
            throw core::Error(
                field + "[" + std::to_string(ijk.x) + "," + std::to_string(ijk.y) + "," + std::to_string(ijk.z) + "]",
                "must be in [0, 1], got " + std::to_string(v));
        }
    }
}

}  // namespace

void validate_phase_mix(const PhaseMix& mix, const core::GridGeometry& geom) {
    if (!std::isfinite(mix.g)) throw core::Error("phase_mix.g", "must be finite (it is clamped to +-0.9999)");
    validate_share(mix.share, geom, "phase_mix.share", "the grid S is computed on");
}

void validate_path_mix(const PathMix& mix, const core::GridGeometry& geom) {
    if (!std::isfinite(mix.g)) throw core::Error("path_mix.g", "must be finite (it is clamped to +-0.9999)");
    if (!(mix.albedo >= 0.0 && mix.albedo <= 1.0))
        throw core::Error("path_mix.albedo", "must be in [0, 1], got " + std::to_string(mix.albedo));
    validate_share(mix.share, geom, "path_mix.share", "the medium's grid");
}

double optical_depth(const LightingMedium& m, const glm::dvec3& a, const glm::dvec3& b) noexcept {
    const glm::dvec3 d = b - a;
    const double len = glm::length(d);
    if (!(len > 0.0) || !std::isfinite(len)) return 0.0;
    return detail::optical_depth_along(m.density.geom, m.density.data.data(), m.optics.extinction, a, d / len, 0.0,
                                       len);
}

double transmittance(const LightingMedium& m, const glm::dvec3& a, const glm::dvec3& b) noexcept {
    return std::exp(-optical_depth(m, a, b));
}

double optical_depth_to_sun(const LightingMedium& m, const glm::dvec3& x, const glm::dvec3& direction) noexcept {
    const double len = glm::length(direction);
    if (!(len > 0.0) || !std::isfinite(len)) return 0.0;
    return detail::optical_depth_along(m.density.geom, m.density.data.data(), m.optics.extinction, x, -direction / len,
                                       0.0, detail::kInf);
}

}  // namespace fulgur::transport
