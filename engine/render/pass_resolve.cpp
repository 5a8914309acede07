// The resolve pass: S toward the camera on the lighting grid, for the flash and for the
// static light, over the directions the view needs (found on the CPU and cached per camera
// and lighting grid; Renderer::needed_directions() reads the same cache).
#include "render/detail/renderer_impl.h"
#include "transport/detail/directions.h"

#include <glad/gl.h>

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <vector>

namespace fulgur::render {

using detail::delete_texture;
using detail::FrameUniforms;
using detail::kResolve;
using detail::make_texture_3d;
using detail::PassTimer;
using detail::SourceSet;

/// The resolve's work group: kResolveTile x kResolveTile x 1 nodes (resolve.comp's local size).
constexpr int kResolveTile = 8;

Renderer::Impl::NeededCache& Renderer::Impl::needed_slot(const core::GridGeometry& lg) const {
    for (NeededCache& c : needed_cache)
        if (c.used && c.geom == lg) return c;
    NeededCache& c = needed_cache[needed_next];
    needed_next = (needed_next + 1) % needed_cache.size();
    c = {};
    c.used = true;
    c.geom = lg;
    return c;
}

const std::vector<std::uint8_t>& Renderer::Impl::active_mask(const core::GridGeometry& lg) const {
    NeededCache& slot = needed_slot(lg);
    if (slot.active_valid) return slot.active;
    std::vector<std::uint8_t>& lit_active = slot.active;
    lit_active.assign(lg.cell_count(), 1);
    if (has_volume) {
        const core::GridGeometry& dg = density.geom;
        // A lighting node is read by samples within one lighting voxel of it; those
        // samples see density within one more density voxel.
        const int reach = int(std::ceil(lg.voxel_size / dg.voxel_size)) + 1;
        for (std::size_t c = 0; c < lit_active.size(); ++c) {
            const core::Int3 n = lg.unindex(c);
            const glm::dvec3 p = lg.centre(n.x, n.y, n.z), v = dg.to_voxel(p);
            const core::Int3 q = dg.clamped_voxel(p);
            // Outside the density grid, the distance to the grid adds to the reach.
            const glm::dvec3 outside =
                glm::max(glm::dvec3(0.0), glm::max(-v, v - glm::dvec3(dg.dims.x, dg.dims.y, dg.dims.z)));
            const double extra = std::max({outside.x, outside.y, outside.z});
            lit_active[c] = double(distance[dg.index(q.x, q.y, q.z)]) <= reach + 1.0 - extra ? 1 : 0;
        }
    }
    slot.active_valid = true;
    slot.tiles.clear();
    return lit_active;
}

const std::vector<std::uint32_t>& Renderer::Impl::active_tiles(const core::GridGeometry& lg) const {
    const std::vector<std::uint8_t>& act = active_mask(lg);
    NeededCache& slot = needed_slot(lg);  // the same slot active_mask filled
    if (!slot.tiles.empty()) return slot.tiles;
    const core::Int3 n = lg.dims;
    const int tx = (n.x + kResolveTile - 1) / kResolveTile, ty = (n.y + kResolveTile - 1) / kResolveTile;
    std::vector<std::uint8_t> hit(std::size_t(tx) * std::size_t(ty) * std::size_t(n.z), 0);
    for (int k = 0; k < n.z; ++k)
        for (int j = 0; j < n.y; ++j)
            for (int i = 0; i < n.x; ++i)
                if (act[lg.index(i, j, k)])
                    hit[(std::size_t(k) * std::size_t(ty) + std::size_t(j / kResolveTile)) * std::size_t(tx) +
                        std::size_t(i / kResolveTile)] = 1;
    for (std::size_t t = 0; t < hit.size(); ++t)
        if (hit[t]) slot.tiles.push_back(std::uint32_t(t));
    return slot.tiles;
}

const std::vector<DirectionUse>& Renderer::Impl::needed_for(const glm::dvec3& cam, const core::GridGeometry& lg,
                                                            int count, double min_weight) const {
    NeededCache& slot = needed_slot(lg);
    if (slot.camera && *slot.camera == cam && slot.count == count && slot.min_weight == min_weight) return slot.needed;
    slot.needed = view_directions(cam, lg, count, active_mask(lg), min_weight);  // active_mask: the same slot
    slot.min_weight = min_weight;
    slot.camera = cam;
    slot.count = count;
    return slot.needed;
}

/// Resolves a source set toward the camera (only when it or the camera changed): returns the
/// texture the march samples (the set's own texture with one direction).
GLuint Renderer::Impl::resolve_set(SourceSet& set, const glm::dvec3& camera, const std::vector<int>& active,
                                   bool must_resolve, PassTimer& timer) {
    if (set.dir_count == 1) return set.tex[0];
    if (!must_resolve) return set.cam_tex;
    const bool rgb = set.format != GL_R32F;
    // The rain's S is read out geometrically between directions (resolve.comp, GEOMETRIC): the
    // drops' forward lobe is narrower than the directions are apart.
    const GLuint p = rgb ? program("resolve_rgb", {{GL_COMPUTE_SHADER, "resolve.comp"}}, "#define RGB 1\n")
                     : &set == &rain_flash
                         ? program("resolve_geometric", {{GL_COMPUTE_SHADER, "resolve.comp"}}, "#define GEOMETRIC 1\n")
                         : program("resolve", {{GL_COMPUTE_SHADER, "resolve.comp"}});
    glUseProgram(p);
    const transport::detail::FoldTable ft = transport::detail::fold_table(set.dir_count);
    GLint idx[27 * 3];
    GLfloat frac[27 * 3];
    for (int c = 0; c < 27; ++c)
        for (int k = 0; k < 3; ++k) {
            idx[c * 3 + k] = ft.index[std::size_t(c)][std::size_t(k)];
            frac[c * 3 + k] = GLfloat(ft.fraction[std::size_t(c)][std::size_t(k)]);
        }
    const core::GridGeometry& g = set.geom;
    glUniform3iv(glGetUniformLocation(p, "u_fold_index"), 27, idx);
    glUniform3fv(glGetUniformLocation(p, "u_fold_fraction"), 27, frac);
    glUniform3i(glGetUniformLocation(p, "u_dims"), g.dims.x, g.dims.y, g.dims.z);
    glBindImageTexture(0, set.cam_tex, 0, GL_TRUE, 0, GL_READ_WRITE, rgb ? GL_RGBA32F : GL_R32F);
    const GLint loc_dirs = glGetUniformLocation(p, "u_dirs"), loc_acc = glGetUniformLocation(p, "u_accumulate");
    const GLint loc_n = glGetUniformLocation(p, "u_samplers");
    GLfloat active_mask[26] = {};
    for (int d : active) active_mask[d] = 1.0f;
    glUniform1fv(glGetUniformLocation(p, "u_active"), 26, active_mask);
    // Only the tiles near non-empty density are resolved: the march reads S elsewhere only
    // where the density (cloud and rain) is zero.
    const std::vector<std::uint32_t>& tiles = active_tiles(g);
    if (tiles.empty()) {
        timer.end(kResolve);
        set.dirty = false;
        set.resolved_camera = camera;
        return set.cam_tex;
    }
    resolve_tiles.upload(tiles.data(), tiles.size() * sizeof(std::uint32_t));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, resolve_tiles.id);
    glUniform2i(glGetUniformLocation(p, "u_tile_counts"), (g.dims.x + kResolveTile - 1) / kResolveTile,
                (g.dims.y + kResolveTile - 1) / kResolveTile);
    // Up to 16 directions per dispatch (unused samplers read the zero texture with weight 0);
    // at least one dispatch so the active tiles of S_cam are written (zeros) even without S.
    constexpr std::size_t kBatch = 16;
    glUniform1i(glGetUniformLocation(p, "u_one_dispatch"), active.size() <= kBatch ? 1 : 0);
    for (std::size_t b = 0; b == 0 || b < active.size(); b += kBatch) {
        GLint dirs[kBatch];
        std::fill(std::begin(dirs), std::end(dirs), -1);
        for (std::size_t k = 0; k < kBatch; ++k) {
            const bool used = b + k < active.size();
            if (used) dirs[k] = active[b + k];
            glBindTextureUnit(GLuint(k), used ? set.tex[std::size_t(active[b + k])] : zero_tex);
        }
        glUniform4iv(loc_dirs, 4, dirs);
        glUniform1i(loc_n, GLint(std::min(kBatch, std::max<std::size_t>(1, active.size() - b))));
        glUniform1i(loc_acc, b == 0 ? 0 : 1);
        if (b > 0) glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
        glDispatchCompute(GLuint(tiles.size()), 1, 1);
    }
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
    timer.end(kResolve);
    set.dirty = false;
    set.resolved_camera = camera;
    return set.cam_tex;
}

/// S toward the camera (r) and the flash's light at the rain toward the camera (g) in one texture
/// on S's grid (pair.comp): the march reads both with the one fetch it makes for S (a second
/// fetch per rain sample cost the march ~10 ms of ~80 at 1280x720 on fulgur-bench render's
/// rain). The rain's is sampled trilinearly at S's nodes, its own grid or a coarser one.
GLuint Renderer::Impl::pair_with_rain(GLuint scam, GLuint rain_scam) {
    const core::GridGeometry& g = flash.geom;
    if (!pair_tex || !(pair_dims == g.dims)) {
        delete_texture(pair_tex);
        pair_tex = make_texture_3d(GL_RG32F, g.dims);
        pair_dims = g.dims;
    }
    const GLuint p = program("pair", {{GL_COMPUTE_SHADER, "pair.comp"}});
    glUseProgram(p);
    glBindTextureUnit(0, scam);
    glBindTextureUnit(1, rain_scam);
    glBindImageTexture(0, pair_tex, 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RG32F);
    const core::GridGeometry& r = rain_flash.geom;
    const glm::dvec3 extent = r.extent();
    glUniform3i(glGetUniformLocation(p, "u_dims"), g.dims.x, g.dims.y, g.dims.z);
    glUniform3f(glGetUniformLocation(p, "u_rain_min"), float(r.origin.x), float(r.origin.y), float(r.origin.z));
    glUniform3f(glGetUniformLocation(p, "u_rain_size"), float(extent.x), float(extent.y), float(extent.z));
    glDispatchCompute(GLuint((g.dims.x + kResolveTile - 1) / kResolveTile),
                      GLuint((g.dims.y + kResolveTile - 1) / kResolveTile), GLuint(g.dims.z));
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
    return pair_tex;
}

/// Resolve: S toward the camera on the lighting grid, for the flash and for the static light
/// (only when S or the camera changed; with one direction S itself). Binds the density (unit
/// 0), the flash's S toward the camera (unit 1), the static light's (unit 6), the sun's
/// transmittance (unit 7), the detail (unit 9) and the ground's scattered flash light (unit 10).
/// With the flash's light at the rain, unit 1 holds both (pair_with_rain).
void Renderer::Impl::resolve_pass(const glm::dvec3& camera, const Settings& st, const FrameUniforms& u,
                                  PassTimer& timer, FrameStats& stats, bool resolve) {
    GLuint scam = zero_tex, stat = zero_tex;
    // The flash's S and, at the rain's points, its light of orders >= 2: the view's needed
    // directions that were uploaded.
    const auto resolve_flash = [&](SourceSet& set, bool count) {
        const bool must_resolve = set.dir_count > 1 && (set.dirty || set.resolved_camera != camera);
        if (must_resolve) timer.begin(kResolve);  // includes the CPU work of finding the needed directions
        const std::vector<DirectionUse>& need = needed_for(camera, set.geom, set.dir_count, st.direction_min_weight);
        if (count) stats.directions_used = int(need.size());
        std::vector<int> active;
        for (const DirectionUse& d : need) {
            if (set.present[std::size_t(d.index)])
                active.push_back(d.index);
            else if (count)
                stats.missing_weight = std::max(stats.missing_weight, d.max_weight);
        }
        return resolve_set(set, camera, active, must_resolve, timer);
    };
    if (u.lit && resolve) scam = resolve_flash(flash, true);
    if (u.rain_source && resolve) scam = pair_with_rain(scam, resolve_flash(rain_flash, false));
    if (u.statics && resolve) {
        // Every direction is present (upload_static); the view's needed ones are resolved.
        const bool must_resolve = statics.dir_count > 1 && (statics.dirty || statics.resolved_camera != camera);
        if (must_resolve) timer.begin(kResolve);
        std::vector<int> active;
        for (const DirectionUse& d : needed_for(camera, statics.geom, statics.dir_count, st.direction_min_weight))
            active.push_back(d.index);
        stat = resolve_set(statics, camera, active, must_resolve, timer);
    }
    glBindTextureUnit(0, has_volume ? density_tex : zero_tex);
    glBindTextureUnit(1, scam);
    glBindTextureUnit(6, stat);
    glBindTextureUnit(7, sun_fine ? sun_tex : zero_tex);
    glBindTextureUnit(9, u.detail ? detail_tex : zero_tex);
    glBindTextureUnit(10, ground_scatter_tex);  // zero outside its cells (and 1x1 zero while there is none)
    // The static light's ground, read only inside its cells (0 while there is none: unbound).
    glBindTextureUnit(11, ground_static_tex);
    last_scam = u.lit && resolve ? scam : 0;
    last_static = u.statics && resolve ? stat : 0;
}

}  // namespace fulgur::render
