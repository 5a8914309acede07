// A tiny bake for the file tests: 8 virtual lights, a 5x4x3 lighting grid, 3 directions
// (times 2 components when small_metadata(..., components = 2)).
#pragma once

#include "basis/basis.h"
#include "fields.h"

#include <vector>

namespace fulgur::test {

inline basis::FgbMetadata small_metadata(basis::Precision prec, core::Int3 dims = {5, 4, 3}, std::size_t ndir = 3,
                                         std::uint32_t components = 1) {
    basis::FgbMetadata m;
    m.components = components;
    m.key = basis::BakeKey::from_description(
        "fulgur_bake=1\nmedium.extinction=0.004\nmedium.albedo=0.99\nmedium.g=0.6\n"
        "lighting.downsample=4\nvirtual_lights.h_usr=1000\n");
    m.lighting.dims = dims;
    m.lighting.voxel_size = 400.0;
    m.lighting.origin = {-1000.0, -800.0, 0.0};
    const std::vector<glm::dvec3> all = transport::output_directions(26);
    m.directions.assign(all.begin(), all.begin() + std::ptrdiff_t(ndir));
    m.lights.x = {-500.0, 500.0};
    m.lights.y = {-400.0, 400.0};
    m.lights.z = {0.0, 600.0};
    m.lights.cloud_base = 600.0;
    m.lights.cloud_top = 1100.0;
    m.lights.base_layer = 1;
    m.compression = {basis::ThresholdMode::Energy, 0.99, prec};
    return m;
}

inline basis::CompressedLight small_light(const basis::FgbMetadata& m, std::uint32_t l) {
    transport::SourceField f(m.lighting, m.directions);
    for (std::size_t d = 0; d < m.directions.size(); ++d) {
        const std::vector<double> v = light_field(m.lighting.dims, 1000 * l + d);
        for (std::size_t i = 0; i < v.size(); ++i) f.direction(d)[i] = float(v[i] * 1e-7);
    }
    basis::HaarTransform<double> plan(m.lighting.dims);
    basis::CompressedLight c = basis::compress_light(l, f, m.compression, plan);
    if (m.components == 2) {  // a second, different field as the multiple-scattering component
        for (std::size_t d = 0; d < m.directions.size(); ++d) {
            const std::vector<double> v = light_field(m.lighting.dims, 1000 * l + d + 500);
            for (std::size_t i = 0; i < v.size(); ++i) f.direction(d)[i] = float(v[i] * 3e-8);
        }
        basis::CompressedLight c2 = basis::compress_light(l, f, m.compression, plan);
        for (auto& b : c2.directions) c.directions.push_back(std::move(b));
    }
    if (l == 5) {  // a light dropped as negligible: no coefficients at all
        for (auto& b : c.directions) {
            b.gamma = b.norm;
            b.index.clear();
            b.value.clear();
            b.scale_exp = 0;
        }
    }
    return c;
}

}  // namespace fulgur::test
