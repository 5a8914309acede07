#include "view/linear_frame.h"

#include <cstddef>
#include <iterator>

namespace fulgur::view {

namespace {

// Settings with every term switched off: no light in the cloud, no sky, stars, ground, glow or
// channel. Each pass turns its own term back on.
render::Settings dark(render::Settings st) {
    st.cloud_lighting = true;
    st.flash_light = st.static_light = st.sun_light = false;
    st.sky = st.ground = st.glow = st.bolt = false;
    st.star_radiance = 0.0;
    st.glare = false;
    return st;
}

}  // namespace

LinearFrame render_linear(StormView& view, const render::Camera& camera, double t, int width, int height,
                          const ViewOptions& options, const transport::SourceField* source, bool passes,
                          const transport::SourceField* rain_source) {
    ViewOptions o = options;
    o.settings.glare = false;
    o.settings.auto_exposure = false;  // radiance: the exposure is not applied, so not metered
    view.render(camera, t, width, height, o, source, rain_source);
    render::Renderer& r = view.renderer();
    LinearFrame f;
    f.width = width;
    f.height = height;
    f.radiance = r.read_hdr();
    if (!passes) return f;

    const render::Settings all = view.frame_settings(o);
    const auto pass = [&](const char* name, render::Settings st) {
        r.render(camera, st, width, height);
        f.passes.push_back({name, r.read_hdr()});
    };
    render::Settings st = dark(all);
    st.flash_light = all.flash_light;
    pass(kLinearPasses[0], st);

    st = dark(all);
    st.static_light = all.static_light;
    st.sun_light = all.sun_light;
    pass(kLinearPasses[1], st);

    st = dark(all);
    st.glow = all.glow;
    pass(kLinearPasses[2], st);

    st = dark(all);
    st.bolt = all.bolt;
    pass(kLinearPasses[3], st);

    // The background: the sky, the stars and the ground (lit by the flash, the sun and the
    // sky) behind the cloud, whose own light is off (cloud_lighting false also keeps the sun's
    // single scattering out while the sun lights the ground).
    st = all;
    st.cloud_lighting = false;
    st.glow = st.bolt = st.glare = false;
    pass(kLinearPasses[4], st);

    // The transmittance: the frame against a unit sky in every direction, with no light.
    st = dark(all);
    st.sky = true;
    st.sky_zenith = st.sky_horizon = glm::dvec3(1.0);
    r.render(camera, st, width, height);
    const std::vector<float> unit = r.read_hdr();
    f.transmittance.resize(unit.size() / 3);
    for (std::size_t p = 0; p < f.transmittance.size(); ++p) f.transmittance[p] = unit[3 * p];
    return f;
}

}  // namespace fulgur::view
