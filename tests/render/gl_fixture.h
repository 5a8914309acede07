// Shared by the GL tests: one headless OSMesa context per test process, one renderer.
#pragma once

#include "core/core.h"
#include "platform/platform.h"
#include "render/render.h"

#include <glm/glm.hpp>

#include <cmath>
#include <memory>

namespace fulgur::test {

inline platform::Context& gl_context() {
    static std::unique_ptr<platform::Context> ctx = platform::create_headless({.width = 64, .height = 64});
    ctx->make_current();
    return *ctx;
}

/// The renderer shared by the tests of one executable (shader compilation and llvmpipe's
/// JIT happen once). Each test sets the volume, source and bolt it needs.
inline render::Renderer& gl_renderer() {
    gl_context();
    static render::Renderer r(gl_context().get_proc_address());
    return r;
}

/// Renders at w x h into the context's framebuffer (resized to match).
inline render::FrameStats render_at(render::Renderer& r, const render::Camera& cam, const render::Settings& st, int w,
                                    int h) {
    platform::Context& ctx = gl_context();
    if (ctx.width() != w || ctx.height() != h) ctx.resize(w, h);
    return r.render(cam, st, w, h);
}

/// Settings that isolate the volume: no sky, ground, bolt, glow, jitter or dither; white flash.
inline render::Settings volume_only() {
    render::Settings st;
    st.sky = st.ground = st.bolt = st.glow = false;
    st.dither = false;
    st.flash_colour = {1.0, 1.0, 1.0};
    st.internal_scale = 1.0;
    return st;
}

/// A grid of `dims` voxels of size `voxel` with its lower corner at `origin`, filled by f(i,j,k).
template <class F>
core::Grid3<float> make_grid(core::Int3 dims, double voxel, glm::dvec3 origin, F f) {
    core::GridGeometry g;
    g.dims = dims;
    g.voxel_size = voxel;
    g.origin = origin;
    core::Grid3<float> grid(g);
    for (int k = 0; k < dims.z; ++k)
        for (int j = 0; j < dims.y; ++j)
            for (int i = 0; i < dims.x; ++i) grid.at(i, j, k) = f(i, j, k);
    return grid;
}

/// A slab 1 km thick (y in [-500, 500]) of density `rho` across the whole view of
/// slab_camera(): 60 x 10 x 60 voxels of 100 m from (-3000, -500, 0).
inline core::Grid3<float> view_slab(float rho) {
    return make_grid({60, 10, 60}, 100.0, {-3000, -500, 0}, [rho](int, int, int) { return rho; });
}

/// 8 km in front of view_slab(), looking at its middle along +y with a 12 degree field: every
/// ray within 6 degrees of the slab's normal.
inline render::Camera slab_camera() {
    render::Camera cam;
    cam.position = {0, -8000, 3000};
    cam.target = {0, 0, 3000};
    cam.vertical_fov_deg = 12.0;
    return cam;
}

/// A smooth Gaussian puff (sigma 5.3 voxels) filling a 32^3 grid of 40 m voxels with its lower
/// corner at `origin`: its image is smooth at every resolution, so sampling does not move its
/// centroid (a hard-edged object's would alias differently at each resolution).
inline core::Grid3<float> gaussian_puff(glm::dvec3 origin) {
    return make_grid({32, 32, 32}, 40.0, origin, [](int i, int j, int k) {
        const double dx = i - 15.5, dy = j - 15.5, dz = k - 15.5;
        return float(std::exp(-(dx * dx + dy * dy + dz * dz) / (2.0 * 5.3 * 5.3)));
    });
}

/// The camera ray through the centre of pixel (x, y) (y from the top), as the shaders build it.
inline glm::dvec3 pixel_ray(const render::Camera& c, int x, int y, int w, int h) {
    const glm::dvec3 fwd = glm::normalize(c.target - c.position);
    const glm::dvec3 right = glm::normalize(glm::cross(fwd, c.up));
    const glm::dvec3 up = glm::cross(right, fwd);
    const double th = std::tan(c.vertical_fov_deg * 3.14159265358979323846 / 360.0), aspect = double(w) / h;
    const double nx = (2.0 * (x + 0.5) / w - 1.0) * th * aspect, ny = (1.0 - 2.0 * (y + 0.5) / h) * th;
    return glm::normalize(fwd + nx * right + ny * up);
}

}  // namespace fulgur::test
