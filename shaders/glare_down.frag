#version 450 core
// One step down the glare pyramid: each texel the mean of the 4x4 finer texels around it
// (four bilinear taps on texel corners).
layout(binding = 0) uniform sampler2D u_fine;

uniform vec2 u_fine_texel;  // 1 / finer size
uniform vec2 u_size;        // this level's size

out vec4 o_radiance;

void main() {
    vec2 uv = gl_FragCoord.xy / u_size;
    vec3 s = textureLod(u_fine, uv + vec2(-1.0, -1.0) * u_fine_texel, 0.0).rgb +
             textureLod(u_fine, uv + vec2(1.0, -1.0) * u_fine_texel, 0.0).rgb +
             textureLod(u_fine, uv + vec2(-1.0, 1.0) * u_fine_texel, 0.0).rgb +
             textureLod(u_fine, uv + vec2(1.0, 1.0) * u_fine_texel, 0.0).rgb;
    o_radiance = vec4(0.25 * s, 1.0);
}
