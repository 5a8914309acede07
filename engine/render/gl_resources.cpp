// Internal to fulgur::render: the validated upload of a source function into a SourceSet.
#include "render/detail/gl_resources.h"

#include "transport/transport.h"

#include <glad/gl.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace fulgur::render::detail {

/// Validates an upload of `channels` floats per cell and writes it into `set` (see
/// SourceUpload: the listed directions replace the set, or are added with keep_others).
void upload_into(SourceSet& set, const char* what, const core::GridGeometry& geometry, int direction_count,
                 const std::vector<int>& directions, const std::vector<std::span<const float>>& values, int channels,
                 bool keep_others) {
    const std::string name(what);
    core::validate_geometry(geometry, name + ": lighting grid");
    (void)transport::output_directions(direction_count);  // throws for a bad count
    if (directions.size() != values.size())
        throw core::Error(name, std::to_string(directions.size()) + " directions but " + std::to_string(values.size()) +
                                    " value arrays");
    const std::size_t cells = geometry.cell_count(), n = cells * std::size_t(channels);
    std::vector<bool> listed(std::size_t(direction_count), false);
    for (std::size_t k = 0; k < directions.size(); ++k) {
        const int dir = directions[k];
        const std::string where = name + ": direction " + std::to_string(dir);
        if (dir < 0 || dir >= direction_count)
            throw core::Error(where, "index out of range [0, " + std::to_string(direction_count) + ")");
        if (listed[std::size_t(dir)]) throw core::Error(where, "listed twice");
        listed[std::size_t(dir)] = true;
        if (values[k].size() != n)
            throw core::Error(where, "has " + std::to_string(values[k].size()) + " values, the lighting grid " +
                                         std::to_string(cells) + " cells" +
                                         (channels > 1 ? " x " + std::to_string(channels) : std::string()));
        for (std::size_t c = 0; c < n; ++c)
            if (!std::isfinite(values[k][c]))
                throw core::Error(where, "value of cell " + std::to_string(c / std::size_t(channels)) +
                                             (channels > 1 ? " channel " + std::to_string(c % std::size_t(channels))
                                                           : std::string()) +
                                             " is not finite");
    }
    const bool fresh = set.ensure(geometry, direction_count);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    for (std::size_t k = 0; k < directions.size(); ++k)
        glTextureSubImage3D(set.tex[std::size_t(directions[k])], 0, 0, 0, 0, geometry.dims.x, geometry.dims.y,
                            geometry.dims.z, channels == 1 ? GL_RED : GL_RGB, GL_FLOAT, values[k].data());
    if (keep_others && !fresh && set.present.size() == listed.size()) {
        for (std::size_t d = 0; d < listed.size(); ++d) set.present[d] = set.present[d] || listed[d];
    } else {
        set.present = listed;
    }
    set.has = std::find(set.present.begin(), set.present.end(), true) != set.present.end();
    set.dirty = true;
}

}  // namespace fulgur::render::detail
