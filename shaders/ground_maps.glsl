// The maps of the light reaching the ground (FrameBlock ground_scatter, ground_static give
// where they lie): read where the ground is shaded (background.glsl) and where rain takes the
// light from above (volume.glsl).

// The irradiance the cloud's scattered flash light gives the ground (W/m^2 at luminance 1),
// averaged over cells of the ground plane (clamped to zero outside them).
layout(binding = 10) uniform sampler2D u_ground_scatter;

// The static light on the ground besides the sun's beam (sky::compose_ground): the cloud's
// scattered sun and sky light and the sky seen past the cloud, per cell in colour.
layout(binding = 11) uniform sampler2D u_ground_static;
// Its part that is the sun's (or moon's) light the cloud scatters down (the rest: the sky's).
layout(binding = 12) uniform sampler2D u_ground_static_sun;

// Where p lies in the static light's cells: their uv (each in [0, 1)), else negative.
vec2 ground_static_uv(vec3 p) {
    vec2 uv = (p.xy - ground_static.xy) * ground_static.zw;
    return ground_static.z > 0.0 && all(greaterThanEqual(uv, vec2(0.0))) && all(lessThan(uv, vec2(1.0))) ? uv
                                                                                                          : vec2(-1.0);
}
