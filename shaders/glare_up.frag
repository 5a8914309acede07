#version 450 core
// One step up the glare pyramid: this level weighted (its share of the point-spread
// function, render::fit_glare) plus the coarser levels' sum, upsampled by four bilinear taps
// half a coarser texel either side (a tent).
layout(binding = 0) uniform sampler2D u_level;   // this level (the way down)
layout(binding = 1) uniform sampler2D u_coarse;  // the coarser levels' weighted sum

uniform float u_weight;
uniform int u_has_coarse;
uniform vec2 u_coarse_texel;  // 1 / coarser size
uniform vec2 u_size;          // this level's size

out vec4 o_radiance;

void main() {
    vec3 s = u_weight * texelFetch(u_level, ivec2(gl_FragCoord.xy), 0).rgb;
    if (u_has_coarse != 0) {
        vec2 uv = gl_FragCoord.xy / u_size;
        vec2 o = 0.5 * u_coarse_texel;
        s += 0.25 * (textureLod(u_coarse, uv + vec2(-o.x, -o.y), 0.0).rgb + textureLod(u_coarse, uv + vec2(o.x, -o.y), 0.0).rgb +
                     textureLod(u_coarse, uv + vec2(-o.x, o.y), 0.0).rgb + textureLod(u_coarse, uv + vec2(o.x, o.y), 0.0).rgb);
    }
    o_radiance = vec4(s, 1.0);
}
