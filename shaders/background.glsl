// What the camera sees behind the cloud: the sky (the same dome that lights the cloud), or the
// ground lit by the flash, the sun and the sky.
// The smooth part (sky gradient, ground) is evaluated per ray-march pixel (internal
// resolution); the stars per output pixel (full resolution: they stay pixel-sharp whatever
// the internal scale). Both are multiplied by the cloud's transmittance.

// The sky dome: a gradient between the horizon and the zenith in sqrt(sin elevation), the
// function that lights the cloud (scene::SkyDome); below the horizon its horizon value.
vec3 sky_gradient(vec3 d) {
    float h = clamp(d.z, 0.0, 1.0);
    return mix(sky_horizon.rgb, sky_zenith.rgb, sqrt(h));
}

// Stars: each cell of a cube map (kStarCells per face edge) holds at most one star, placed
// well inside its cell and drawn as a Gaussian spot of fixed size in pixels (sigma 0.6 px, cut
// at kStarSpot pixels, where it is 4e-6 of its peak, so that a star reaches a bounded set of
// pixels: star_points.vert draws them), with a brightness from a steep power law (many faint
// stars, few bright ones). One hash per pixel decides presence, position, brightness and tint.
// Deterministic.
const float kStarCells = 160.0;
const float kStarProbability = 0.07;
const float kStarSpot = 3.0;  // pixels (mirrored by kStarSpotPixels in pass_composite.cpp)

// The draws of a cell's star, each in [0, 1]: x its presence (a star when < kStarProbability),
// yz its position in the cell, w its brightness and tint.
vec4 star_draws(vec2 cell, uint face) {
    uint h = hash_u32(uvec3(uvec2(cell), face));
    return vec4(uvec4(h, h >> 8u, h >> 16u, h >> 24u) & 255u) * (1.0 / 255.0);
}

// Where a cell's star is on its face ([-1, 1]^2).
vec2 star_position(vec2 cell, vec4 draws) { return ((cell + 0.35 + 0.3 * draws.yz) / kStarCells) * 2.0 - 1.0; }

// The (unnormalized) direction of face coordinates uv on a face: stars()' projection undone.
vec3 cube_face_direction(uint face, vec2 uv) {
    float s = (face & 1u) == 1u ? 1.0 : -1.0;
    return face < 2u ? vec3(s, uv.x, uv.y) : face < 4u ? vec3(uv.y, s, uv.x) : vec3(uv.x, uv.y, s);
}

vec3 stars(vec3 d, float pixel_angle) {
    // Cube face of d without dynamic vector indexing (slow on SIMD software rasterizers).
    vec3 ad = abs(d);
    vec2 uv;
    float major;
    uint face;
    if (ad.x >= ad.y && ad.x >= ad.z) {
        uv = d.yz;
        major = ad.x;
        face = d.x > 0.0 ? 1u : 0u;
    } else if (ad.y >= ad.z) {
        uv = d.zx;
        major = ad.y;
        face = d.y > 0.0 ? 3u : 2u;
    } else {
        uv = d.xy;
        major = ad.z;
        face = d.z > 0.0 ? 5u : 4u;
    }
    uv /= major;                                            // [-1, 1]^2 on the face
    vec2 cell = floor((uv * 0.5 + 0.5) * kStarCells);
    vec4 u = star_draws(cell, face);
    vec2 star = star_position(cell, u);
    // Angular distance on the cube face: d(angle) = d(uv) / (1 + |uv|^2) (exact at the face
    // centre and along radial lines; stars near face edges are slightly elongated).
    float r = length(star - uv) / ((1.0 + dot(uv, uv)) * pixel_angle);  // pixels
    float b2 = u.w * u.w, b4 = b2 * b2;
    float brightness = b4 * b4 * b4;                          // u^12
    vec3 tint = mix(vec3(1.0, 0.85, 0.7), vec3(0.8, 0.9, 1.0), fract(u.w * 7.0));
    float present = u.x < kStarProbability ? 1.0 : 0.0;
    float spot = r < kStarSpot ? exp(-r * r * (0.5 / 0.36)) : 0.0;
    return (present * sky_params.y * brightness * spot) * tint;
}

vec3 sky_radiance(vec3 d) {
    if (sky_params.z < 0.5) return vec3(0.0);
    return sky_gradient(d);
}

// Stars over the sky (not over the ground), fading out toward the horizon (extinction).
vec3 star_radiance(vec3 o, vec3 d, float pixel_angle) {
    if (sky_params.z < 0.5 || ground_distance(o, d) < kBig) return vec3(0.0);
    return d.z > 0.0 ? stars(d, pixel_angle) * smoothstep(0.0, 0.08, d.z) : vec3(0.0);
}

#ifndef SUN_TRANSMITTANCE_DECLARED
#define SUN_TRANSMITTANCE_DECLARED
// Transmittance from the sun to each full-resolution voxel (the density grid).
layout(binding = 7) uniform sampler3D u_sun_t;
#endif

// Transmittance from p toward the sun: outside the cloud's box nothing absorbs, so it is the
// full-resolution transmittance where the ray to the sun enters the box (1 if it misses it).
// It is read where the ray reaches the box of the voxels' centres, which hold the
// transmittance: at the box's face the texture would clamp to the first layer of centres
// straight above (or beside) the entry point, moving the shadow toward the sun by half a voxel
// over the tangent of the sun's elevation. The half voxel between the face and the centres
// holds the outer layer's density, which no cloud away from the box's faces has.
float sun_visibility(vec3 p) {
    if (sun_params.y < 0.5 || vol_size.w <= 0.0) return 1.0;
    vec3 to_sun = -sun_dir.xyz;
    vec3 lo = vol_min.xyz + 0.5 * vol_size.w, hi = vol_min.xyz + vol_size.xyz - 0.5 * vol_size.w;
    vec3 inv = 1.0 / vec3(abs(to_sun.x) < 1e-9 ? 1e-9 : to_sun.x, abs(to_sun.y) < 1e-9 ? 1e-9 : to_sun.y,
                          abs(to_sun.z) < 1e-9 ? 1e-9 : to_sun.z);
    vec3 ta = (lo - p) * inv, tb = (hi - p) * inv;
    vec3 tmin = min(ta, tb), tmax = max(ta, tb);
    float t0 = max(max(tmin.x, tmin.y), max(tmin.z, 0.0)), t1 = min(min(tmax.x, tmax.y), tmax.z);
    if (t1 < t0) return 1.0;
    vec3 q = p + t0 * to_sun;
    return textureLod(u_sun_t, (q - vol_min.xyz) / vol_size.xyz, 0.0).r;
}

#if HAS_RAIN
// Transmittance of the rain between a ground point p and a light at q: the part of the segment
// below the rain's top, sampled at 4 points (the rain varies over hundreds of metres), at the
// share of its extinction the light solves carry (rain_lights.z).
float rain_transmittance(vec3 p, vec3 q) {
    vec3 l = q - p;
    float f = l.z > 1e-3 ? clamp((rain_params.z - p.z) / l.z, 0.0, 1.0) : 1.0;
    float tau = 0.0;
    for (int k = 0; k < 4; ++k) {
        vec3 x = p + ((float(k) + 0.5) * 0.25 * f) * l;
        tau += textureLod(u_density, (x - vol_min.xyz) / vol_size.xyz, 0.0).b;
    }
    return exp(-rain_params.x * rain_lights.z * tau * 0.25 * f * length(l));
}

// The ground lights' rain transmittance tabulated per light (render/pass_ground_rain.cpp,
// ground_rain.comp): layer i holds light i's on a polar map around its foot. x is the azimuth
// (texel a at 2 pi (a + 0.5) / width, repeating), y the distance r from the foot as r / (r + R)
// (R: ground_rain_scale), so the map reaches every point of the ground, finest near the foot
// where the path is steepest. GROUND_RAIN_MAP 1 (compile time): the ground reads the map;
// 0: each pixel integrates its paths (rain_transmittance).
#ifndef GROUND_RAIN_MAP
#define GROUND_RAIN_MAP 0
#endif

// The polar map's radial scale for a light at q: its height over the ground (the distance over
// which the path's slope changes), at least 4 density voxels.
float ground_rain_scale(vec3 q) { return max(q.z - ground_params.x, 4.0 * vol_size.w); }

#if GROUND_RAIN_MAP
layout(binding = 12) uniform sampler2DArray u_ground_rain;
#endif

// The rain's transmittance between the ground point p and ground light i.
float ground_light_rain(vec3 p, int i) {
#if GROUND_RAIN_MAP
    vec2 d = p.xy - ground_light[i].xy;
    float r = length(d);
    // atan(y, x) is undefined at x = y = 0; there r = 0 and every azimuth holds the foot's value.
    float azimuth = atan(d.y, d.x + 1e-30) * 0.15915494;
    return textureLod(u_ground_rain, vec3(azimuth, r / (r + ground_rain_scale(ground_light[i].xyz)), float(i)), 0.0).r;
#else
    return rain_transmittance(p, ground_light[i].xyz);
#endif
}
#endif

// The irradiance the cloud's scattered flash light gives the ground (W/m^2 at luminance 1),
// averaged over cells of the ground plane (clamped to zero outside them).
layout(binding = 10) uniform sampler2D u_ground_scatter;

// GROUND_LIGHTS 0 and GROUND_SCATTER 0 (compile time, the march's programs when the frame has
// no ground lights, no scattered light on the ground: render/pass_march.cpp). A software
// rasterizer runs a loop's body at least once and both sides of every test, so read from the
// uniforms every pixel paid a light's and the scattered light's rain transmittance (8 density
// reads) with neither there (between flashes: storm-full's march at 1280x720 59.5-60.1 ->
// 54.6-56.3 ms, the same frame). Frames that have them read the count and the test from the
// uniforms: the loop unrolled for 6 lights and the scattered light without its test measured
// slower (the flash's march 86 -> 90 and 96 ms). Undefined (-1): read from the uniforms.
#ifndef GROUND_LIGHTS
#define GROUND_LIGHTS -1
#endif
#ifndef GROUND_SCATTER
#define GROUND_SCATTER -1
#endif

// The ground's irradiance from the flash, in its colour: the channel as a few point lights
// (intensity already multiplied by their visibility through the cloud), through the rain, and
// the light the cloud scatters down (through the rain straight above the point).
vec3 ground_flash_irradiance(vec3 p) {
    vec3 E = vec3(0.0);
#if GROUND_SCATTER != 0
    if (ground_scatter.z > 0.0) {
#else
    if (false) {
#endif
        float e = textureLod(u_ground_scatter, (p.xy - ground_scatter.xy) * ground_scatter.zw, 0.0).r;
#if HAS_RAIN
        e *= rain_transmittance(p, vec3(p.xy, rain_params.z));
#endif
        E += light_colour.rgb * e;
    }
#if GROUND_LIGHTS != 0
    int n = int(ground_params.w);
#else
    const int n = 0;
#endif
    for (int i = 0; i < n; ++i) {
        vec3 l = ground_light[i].xyz - p;
        float r2 = max(dot(l, l), 1.0);
        float cos_theta = max(l.z, 0.0) * inversesqrt(r2);
#if HAS_RAIN
        E += light_colour.rgb * (ground_light[i].w * cos_theta / r2 * ground_light_rain(p, i));
#else
        E += light_colour.rgb * (ground_light[i].w * cos_theta / r2);
#endif
    }
    return E;
}

// The static light on the ground besides the sun's beam (sky::compose_ground): the cloud's
// scattered sun and sky light and the sky seen past the cloud, per cell in colour.
layout(binding = 11) uniform sampler2D u_ground_static;

// The rest of the ground's irradiance: on the static light's cells, their irradiance (the
// cloud's light and the sky it leaves); elsewhere (or without them) the sky's on a horizontal
// plane, pi (0.2 horizon + 0.8 zenith) for the gradient; then the sun through the cloud (its
// shadow), added to E in that order.
vec3 ground_static_irradiance(vec3 p, vec3 E) {
    vec2 uv = (p.xy - ground_static.xy) * ground_static.zw;
    if (ground_static.z > 0.0 && all(greaterThanEqual(uv, vec2(0.0))) && all(lessThan(uv, vec2(1.0))))
        E += textureLod(u_ground_static, uv, 0.0).rgb;
    else
        E += sky_params.z > 0.5 ? 3.14159265 * (0.2 * sky_horizon.rgb + 0.8 * sky_zenith.rgb) : vec3(0.0);
    if (sun_dir.w > 0.5 && sun_dir.z < 0.0) E += sun_rgb.rgb * (-sun_dir.z * sun_visibility(p));
    return E;
}

// The ground's reflectance at p: Lambertian, with a mild, low-frequency variation (fields,
// forest) so the plane reads as ground; divided by pi.
// The GROUND_* constants are render::GroundLook's (render.h), defined by the renderer.
vec3 ground_albedo(vec3 p) {
    vec2 g = p.xy / GROUND_CELL_M;
    vec2 gi = floor(g), gf = fract(g);
    gf = gf * gf * (3.0 - 2.0 * gf);
    const int s = int(GROUND_SEED);
    float n00 = hash_unit(hash_u32(uvec3(ivec3(gi, s)))), n10 = hash_unit(hash_u32(uvec3(ivec3(gi + vec2(1, 0), s))));
    float n01 = hash_unit(hash_u32(uvec3(ivec3(gi + vec2(0, 1), s)))), n11 = hash_unit(hash_u32(uvec3(ivec3(gi + vec2(1, 1), s))));
    float variation = mix(mix(n00, n10, gf.x), mix(n01, n11, gf.x), gf.y);
    return ground_params.y * (GROUND_LOW + GROUND_SPAN * variation) * GROUND_TINT;
}

// Haze toward the horizon over a ground distance t (aerial perspective toward the horizon colour).
float ground_haze(float t) { return 1.0 - exp(-t / GROUND_HAZE_M); }
vec3 haze_colour(vec3 d) { return sky_params.z > 0.5 ? sky_gradient(vec3(d.xy, 0.0)) : vec3(0.0); }

// Ground: Lambertian, lit by the channel, the sun and the sky; hazy with distance.
vec3 ground_radiance(vec3 p, vec3 d, float t) {
    vec3 E = ground_static_irradiance(p, ground_flash_irradiance(p));
    vec3 L = ground_albedo(p) * E;
    return mix(L, haze_colour(d), ground_haze(t));
}

// The smooth background (no stars).
vec3 background(vec3 o, vec3 d) {
    float tg = ground_distance(o, d);
    if (tg < kBig) return ground_radiance(o + tg * d, d, tg);
    if (ground_params.z > 0.5 && d.z < 0.0 && o.z <= ground_params.x) return vec3(0.0);  // under the ground
    return sky_radiance(d);
}

// The smooth background in two parts whose sum is background(o, d) (to rounding): what the
// channel lights (`flash`: the ground's flash light) and the rest (`rest`: sky, sunlit and
// skylit ground, haze). Each is kept apart by the temporal history (docs/render.md).
void background_parts(vec3 o, vec3 d, out vec3 rest, out vec3 flash) {
    flash = vec3(0.0);
    float tg = ground_distance(o, d);
    if (tg < kBig) {
        vec3 p = o + tg * d;
        vec3 albedo = ground_albedo(p);
        float haze = ground_haze(tg);
        flash = albedo * ground_flash_irradiance(p) * (1.0 - haze);
        rest = mix(albedo * ground_static_irradiance(p, vec3(0.0)), haze_colour(d), haze);
        return;
    }
    rest = ground_params.z > 0.5 && d.z < 0.0 && o.z <= ground_params.x ? vec3(0.0) : sky_radiance(d);
}
