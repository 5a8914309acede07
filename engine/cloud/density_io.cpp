#include "cloud/cloud.h"

#include <string>

namespace fulgur::cloud {

core::Grid3<float> load_density(const std::filesystem::path& path) {
    core::Grid3<float> g = core::read_nrrd(path);
    for (std::size_t i = 0; i < g.data.size(); ++i) {
        const float v = g.data[i];
        if (!(v >= 0.0f && v <= 1.0f)) {
            const core::Int3 c = g.geom.unindex(i);
            throw core::Error(path.string() + ": voxel (" + std::to_string(c.x) + "," + std::to_string(c.y) + "," +
                                  std::to_string(c.z) + ")",
                              "density " + std::to_string(v) + " is outside [0, 1]");
        }
    }
    return g;
}

void save_density(const std::filesystem::path& path, const core::Grid3<float>& density) {
    core::write_nrrd(path, density, "fulgur cloud density in [0,1]");
}

double cloud_base_height(const core::Grid3<float>& density, float threshold) {
    const core::Int3 d = density.dims();
    for (int k = 0; k < d.z; ++k)
        for (int j = 0; j < d.y; ++j)
            for (int i = 0; i < d.x; ++i)
                if (density.at(i, j, k) > threshold) return density.geom.origin.z + k * density.geom.voxel_size;
    return density.geom.upper().z;
}

}  // namespace fulgur::cloud
