#version 450 core
// Exposure metering: a histogram of the ray march's luminance (cloud, glow, background) in
// log2 bins, read back by the renderer, which picks the exposure from it. It counts one pixel
// of each u_stride x u_stride block (Settings::meter_stride), the block's lower left. Each work
// group fills a shared histogram over a tile of 32x32 counted pixels (each invocation a 4x4
// block of them) and adds it to the global one: few global atomics, and the shared histogram's
// clearing and flushing (a bin per invocation per 16 bins) spread over 1024 pixels instead of 64.
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 3) uniform sampler2D u_march;
layout(std430, binding = 3) buffer Histogram { uint bins[]; };

uniform int u_bins;         // number of bins
uniform float u_log2_min;   // lower edge of bin 0 (log2 of radiance)
uniform float u_bin_width;  // in log2 units
uniform int u_stride;       // one counted pixel per u_stride x u_stride block

shared uint local_bins[1024];  // at least u_bins (render/pass_meter.cpp)

void main() {
    uint li = gl_LocalInvocationIndex;
    for (uint b = li; b < uint(u_bins); b += 64u) local_bins[b] = 0u;
    barrier();
    ivec2 base = ivec2(gl_GlobalInvocationID.xy) * 4;
    for (int j = 0; j < 16; ++j) {
        ivec2 p = (base + ivec2(j & 3, j >> 2)) * u_stride;
        if (p.x >= int(sizes.z) || p.y >= int(sizes.w)) continue;
        float y = luminance(texelFetch(u_march, p, 0).rgb);
        // Black pixels (and anything below the range) go to bin 0.
        int bin = y > 0.0 ? clamp(int(floor((log2(y) - u_log2_min) / u_bin_width)), 0, u_bins - 1) : 0;
        atomicAdd(local_bins[bin], 1u);
    }
    barrier();
    for (uint b = li; b < uint(u_bins); b += 64u)
        if (local_bins[b] != 0u) atomicAdd(bins[b], local_bins[b]);
}
