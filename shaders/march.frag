#version 450 core
// Ray march, fragment-shader variant (full-screen triangle at internal resolution).
#include "march_pixel.glsl"

out vec4 o_result;

void main() { o_result = shade_pixel(gl_FragCoord.xy); }
