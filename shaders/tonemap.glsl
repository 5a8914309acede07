// The display transform shared by composite.frag and display.frag: the exposed radiance through
// the filmic tone curve, sRGB-encoded, with an optional 8-bit dither. Needs common.glsl (hash_u32).

// ACES filmic tone curve, Stephen Hill's fit of the RRT + ODT (sRGB, 100 nits): linear
// sRGB -> the fit's space (input matrix: the RRT's saturation and gamut, grey kept), the
// rational curve, back (output matrix). Its shoulder is soft: display white (0.996 linear,
// 8-bit 255) is reached only at ~20x the exposed grey level 1, 2 stops beyond a plain
// Reinhard-like clip, so bright cloud near the channel keeps its falloff instead of a white
// plateau. Matrices are column-major (GLSL), Hill's rows transposed.
const mat3 kAcesInput = mat3(0.59719, 0.07600, 0.02840, 0.35458, 0.90834, 0.13383, 0.04823, 0.01566, 0.83777);
const mat3 kAcesOutput = mat3(1.60475, -0.10208, -0.00327, -0.53108, 1.10813, -0.07276, -0.07367, -0.00605, 1.07602);

vec3 aces_fitted(vec3 x) {
    // Past 1e4 the curve is white to 4e-5 (its limit is 1.0165, clamped to 1); without this a
    // radiance times exposure beyond ~1e19 would square past float32 and divide inf by inf.
    vec3 v = kAcesInput * min(x, vec3(1e4));
    vec3 a = v * (v + 0.0245786) - 0.000090537;
    vec3 b = v * (0.983729 * v + 0.4329510) + 0.238081;
    return clamp(kAcesOutput * (a / b), 0.0, 1.0);
}

// sRGB encoding. The power 1/2.4 is approximated with three square roots (Ian Taylor's
// fit; max error 0.4 of an 8-bit level over [0, 1]; pow() costs a log2 and an
// exp2 per channel on a software rasterizer).
vec3 srgb_encode(vec3 c) {
    vec3 s1 = sqrt(c), s2 = sqrt(s1), s3 = sqrt(s2);
    vec3 curve = 0.585122381 * s1 + 0.783140355 * s2 - 0.368262736 * s3;
    return mix(12.92 * c, curve, step(0.0031308, c));
}

// Radiance `hdr` at exposure `exposure` as display values in [0, 1]; with `dither`, plus a
// triangular dither of +-1 LSB (the sum of two 16-bit uniforms from one hash of the pixel and
// the frame index), deterministic per frame.
vec3 display_encode(vec3 hdr, float exposure, bool dither, uvec2 pixel) {
    vec3 c = srgb_encode(aces_fitted(hdr * exposure));
    if (dither) {
        uint h = hash_u32(uvec3(pixel, uint(counts.y)));
        float n = float(h & 0xffffu) * (1.0 / 65535.0) + float(h >> 16u) * (1.0 / 65535.0) - 1.0;
        c += n / 255.0;
    }
    return c;
}
