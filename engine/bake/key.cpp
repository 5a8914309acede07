// The scene key (bake.h): a hash of every scene parameter a bake's bytes depend on, with the
// canonical description it is computed from, so a stale .fgb names what changed.
#include "bake/bake.h"

#include <sstream>
#include <string_view>

namespace fulgur::bake {

namespace {

// Bump when the bake's algorithm changes what it writes for the same scene (forces a rebake).
// 2: the lattice-Boltzmann thick-voxel mapping (transport.lattice_boltzmann.thick_voxels).
constexpr int kBakeAlgorithm = 2;

std::uint64_t hash_bytes(const void* data, std::size_t n) noexcept {
    return basis::hash_description(std::string_view(static_cast<const char*>(data), n));
}

}  // namespace

// ---------------------------------------------------------------------------------------

basis::BakeKey scene_key(const scene::Scene& s, const core::Grid3<float>& density) {
    std::ostringstream d;
    const bool multiple = s.effects.multiple_scattering;
    d << "bake.algorithm=" << kBakeAlgorithm << "\n";
    d << "density.dims=" << density.dims().x << "x" << density.dims().y << "x" << density.dims().z << "\n";
    d << "density.voxel_size=" << core::format_number(density.geom.voxel_size, 17) << "\n";
    d << "density.origin=" << core::format_number(density.geom.origin.x, 17) << ","
      << core::format_number(density.geom.origin.y, 17) << "," << core::format_number(density.geom.origin.z, 17)
      << "\n";
    char hx[24];
    std::snprintf(
        hx, sizeof hx, "%016llx",
        static_cast<unsigned long long>(hash_bytes(density.data.data(), density.data.size() * sizeof(float))));
    d << "density.hash=" << hx << "\n";
    d << "medium.extinction=" << core::format_number(s.medium.extinction, 17) << "\n";
    d << "medium.albedo=" << core::format_number(s.medium.albedo, 17) << "\n";
    d << "medium.g=" << core::format_number(s.medium.g, 17) << "\n";
    d << "lighting.downsample=" << s.lighting_downsample << "\n";
    d << "lighting.directions=" << s.effective_directions() << "\n";
    d << "effects.single_scattering=" << s.effects.single_scattering << "\n";
    d << "effects.multiple_scattering=" << multiple << "\n";
    d << "transport.single_scattering.tolerance=" << core::format_number(s.transport.ss_tolerance, 17) << "\n";
    if (s.transport.refine != 1) d << "transport.refine=" << s.transport.refine << "\n";
    if (multiple) {
        if (s.transport.solver == scene::TransportSettings::Solver::LatticeBoltzmann) {
            d << "transport.solver=lattice_boltzmann\n";
            d << "transport.lattice_boltzmann.collision=" << s.transport.lb_collision << "\n";
            d << "transport.lattice_boltzmann.absorption=" << s.transport.lb_absorption << "\n";
            d << "transport.lattice_boltzmann.thick_voxels=" << s.transport.lb_thick_voxels << "\n";
            d << "transport.lattice_boltzmann.tolerance=" << core::format_number(s.transport.lb_tolerance, 17) << "\n";
            d << "transport.lattice_boltzmann.max_iterations=" << s.transport.lb_max_iterations << "\n";
            if (s.transport.lb_exact_orders != 1)
                d << "transport.lattice_boltzmann.exact_orders=" << s.transport.lb_exact_orders
                  << "\ntransport.lattice_boltzmann.order2_paths=" << s.transport.lb_order2_paths << "\n";
        } else {
            d << "transport.solver=monte_carlo\n";
            d << "transport.monte_carlo.paths=" << s.transport.mc_paths << "\n";
            d << "transport.monte_carlo.seed=" << s.transport.mc_seed << "\n";
            d << "transport.monte_carlo.batches=" << s.transport.mc_batches << "\n";
        }
    }
    const basis::VirtualLightParams& v = s.virtual_lights;
    d << "virtual_lights.h_usr=" << core::format_number(v.h_usr, 17) << "\n";
    d << "virtual_lights.epsilon=" << core::format_number(v.epsilon, 17) << "\n";
    d << "virtual_lights.margin=" << core::format_number(v.margin, 17) << "\n";
    d << "virtual_lights.ground_height=" << core::format_number(v.ground_height, 17) << "\n";
    d << "virtual_lights.density_threshold=" << core::format_number(v.density_threshold, 17) << "\n";
    d << "virtual_lights.drop_below=" << core::format_number(s.drop_below, 17) << "\n";
    const basis::CompressionParams& c = s.compression;
    d << "compression.threshold=" << basis::to_string(c.mode) << "\n";
    d << "compression.xi=" << core::format_number(c.xi, 17) << "\n";
    d << "compression.precision=" << basis::to_string(c.precision) << "\n";
    d << "compression.decomposition=" << basis::to_string(c.decomposition) << "\n";
    d << "compression.entropy=" << basis::to_string(c.entropy) << "\n";
    d << "compression.components=" << (s.separate_components ? "separate" : "combined") << "\n";
    return basis::BakeKey::from_description(d.str());
}

}  // namespace fulgur::bake
