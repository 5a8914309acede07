// Density import/export (NRRD) and simple measurements of a density grid.
#include "cloud/cloud.h"

#include <string>

namespace fulgur::cloud {

namespace {

std::string voxel_name(const core::GridGeometry& g, std::size_t index) {
    const core::Int3 c = g.unindex(index);
    return "voxel (" + std::to_string(c.x) + "," + std::to_string(c.y) + "," + std::to_string(c.z) + ")";
}

// Throws naming `where` and the first voxel whose value is not in [0, 1] (NaN included).
void check_range(const core::Grid3<float>& g, const std::string& where) {
    for (std::size_t i = 0; i < g.data.size(); ++i) {
        const float v = g.data[i];
        if (!(v >= 0.0f && v <= 1.0f))
            throw core::Error(where + ": " + voxel_name(g.geom, i),
                              "density " + core::format_number(v, 9) + " is outside [0, 1]");
    }
}

}  // namespace

core::Grid3<float> load_density(const std::filesystem::path& path) {
    core::Grid3<float> g = core::read_nrrd(path);
    check_range(g, path.string());
    return g;
}

void save_density(const std::filesystem::path& path, const core::Grid3<float>& density) {
    FULGUR_ASSERT(density.data.size() == density.geom.cell_count(), "density data size does not match its dimensions");
    core::validate_geometry(density.geom, path.string());
    check_range(density, path.string());
    core::write_nrrd(path, density, "fulgur cloud density in [0,1]");
}

double cloud_base_height(const core::Grid3<float>& density, float threshold) {
    const core::Int3 d = density.dims();
    const std::size_t layer = std::size_t(d.x) * std::size_t(d.y);
    for (int k = 0; k < d.z; ++k) {
        const float* p = density.data.data() + std::size_t(k) * layer;
        for (std::size_t q = 0; q < layer; ++q)
            if (p[q] > threshold) return density.geom.origin.z + k * density.geom.voxel_size;
    }
    return density.geom.upper().z;
}

double cloud_top_height(const core::Grid3<float>& density, float threshold) {
    const core::Int3 d = density.dims();
    const std::size_t layer = std::size_t(d.x) * std::size_t(d.y);
    for (int k = d.z - 1; k >= 0; --k) {
        const float* p = density.data.data() + std::size_t(k) * layer;
        for (std::size_t q = 0; q < layer; ++q)
            if (p[q] > threshold) return density.geom.origin.z + (k + 1) * density.geom.voxel_size;
    }
    return density.geom.origin.z;
}

}  // namespace fulgur::cloud
