// Reconstruction of bases and weighted sums of bases, from compressed or raw data, and
// their export as NRRD float32 (ParaView, 3D Slicer).
#include "basis/export.h"

#include <cmath>
#include <sstream>

namespace fulgur::basis {

namespace {

std::string describe(std::span<const WeightedLight> lights, std::size_t direction,
                     const std::vector<glm::dvec3>& dirs) {
    std::ostringstream s;
    s.precision(6);
    s << "direction " << direction;
    if (direction < dirs.size())
        s << " (" << dirs[direction].x << "," << dirs[direction].y << "," << dirs[direction].z << ")";
    s << ", sum of";
    std::size_t shown = 0;
    for (const WeightedLight& l : lights) {
        if (shown++ == 16) {
            s << " ... (" << lights.size() << " lights)";
            break;
        }
        s << ' ' << l.weight << "*light" << l.light;
    }
    return s.str();
}

}  // namespace

core::Grid3<float> reconstruct(const BakedBasis& baked, std::span<const WeightedLight> lights, std::size_t direction) {
    const FgbMetadata& m = baked.meta;
    if (direction >= m.directions.size())
        throw core::Error("reconstruct", "direction " + std::to_string(direction) + " does not exist (the bake has " +
                                             std::to_string(m.directions.size()) + ")");
    std::vector<double> coeffs(m.cells(), 0.0);
    for (const WeightedLight& wl : lights) {
        if (wl.light >= baked.lights.size())
            throw core::Error("reconstruct", "light " + std::to_string(wl.light) + " does not exist (the bake has " +
                                                 std::to_string(baked.lights.size()) + ")");
        if (!std::isfinite(wl.weight))
            throw core::Error("reconstruct", "the weight of light " + std::to_string(wl.light) + " is not finite");
        const CompressedLight& cl = baked.lights[wl.light];
        FULGUR_ASSERT(cl.directions.size() == m.bases(), "reconstruct: light without all bases");
        for (std::size_t c = 0; c < m.components; ++c)
            accumulate(cl.directions[m.basis_index(c, direction)], wl.weight, coeffs);
    }
    HaarTransform<double> plan(m.lighting.dims, m.compression.decomposition);
    plan.inverse(coeffs);
    core::Grid3<float> out(m.lighting);
    for (std::size_t i = 0; i < coeffs.size(); ++i) out.data[i] = float(coeffs[i]);
    return out;
}

core::Grid3<float> weighted_sum(std::span<const WeightedLight> lights, std::size_t direction,
                                const std::function<const transport::SourceField&(std::uint32_t)>& field_of) {
    if (lights.empty()) throw core::Error("weighted_sum", "needs at least one light");
    const transport::SourceField& first = field_of(lights.front().light);
    if (direction >= first.directions.size())
        throw core::Error("weighted_sum", "direction " + std::to_string(direction) + " does not exist (the field has " +
                                              std::to_string(first.directions.size()) + ")");
    std::vector<double> sum(first.cells(), 0.0);
    for (const WeightedLight& wl : lights) {
        const transport::SourceField& f = field_of(wl.light);
        if (!(f.geom == first.geom) || f.directions.size() != first.directions.size())
            throw core::Error("weighted_sum", "the field of light " + std::to_string(wl.light) +
                                                  " has another grid or direction count than light " +
                                                  std::to_string(lights.front().light) + "'s");
        if (!std::isfinite(wl.weight))
            throw core::Error("weighted_sum", "the weight of light " + std::to_string(wl.light) + " is not finite");
        const std::span<const float> s = f.direction(direction);
        for (std::size_t i = 0; i < s.size(); ++i) sum[i] += wl.weight * double(s[i]);
    }
    core::Grid3<float> out(first.geom);
    for (std::size_t i = 0; i < sum.size(); ++i) out.data[i] = float(sum[i]);
    return out;
}

void export_compressed_nrrd(const std::filesystem::path& path, const BakedBasis& baked,
                            std::span<const WeightedLight> lights, std::size_t direction) {
    const core::Grid3<float> g = reconstruct(baked, lights, direction);
    std::ostringstream c;
    c << "Fulgur source function S, reconstructed from the compressed bake (threshold "
      << to_string(baked.meta.compression.mode) << " xi=" << baked.meta.compression.xi << ", "
      << to_string(baked.meta.compression.precision) << ", " << to_string(baked.meta.compression.decomposition)
      << " Haar, no ambient term), " << describe(lights, direction, baked.meta.directions);
    core::write_nrrd(path, g, c.str());
}

void export_raw_nrrd(const std::filesystem::path& path, std::span<const WeightedLight> lights, std::size_t direction,
                     const std::function<const transport::SourceField&(std::uint32_t)>& field_of) {
    const core::Grid3<float> g = weighted_sum(lights, direction, field_of);
    const std::string c = "Fulgur source function S, uncompressed, " +
                          describe(lights, direction, field_of(lights.front().light).directions);
    core::write_nrrd(path, g, c);
}

}  // namespace fulgur::basis
