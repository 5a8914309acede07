#version 450 core
in float v_across;
in vec3 v_radiance;
out vec4 o_radiance;

void main() {
    // Parabolic profile across the ribbon with mean 1: soft, anti-aliased edges.
    o_radiance = vec4(v_radiance * (1.5 * max(1.0 - v_across * v_across, 0.0)), 1.0);
}
