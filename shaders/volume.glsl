// The cloud volume: density texture with its empty-space distance, the view-resolved source
// function, and the ray marcher.
//
// Compile-time switches (set by the renderer):
//   SKIP_EMPTY   1: jump over space the Chebyshev distance field proves empty
//   EARLY_EXIT   1: stop once the transmittance is below march_params.y
//   HAS_SOURCE   1: S is present (0: the cloud only absorbs; no S fetch at all)
//   HAS_STATIC   1: the static light's S in colour (sun, moon, sky: u_static) is present
//   HAS_SUN      1: the sun's single scattering at full resolution (u_sun_t)
//   HAS_EMISSION 1: track the transmittance up to the glow's depth
//   HAS_DETAIL   1: erode the density by the sub-voxel detail (u_detail, detail_params)
//   HAS_RAIN     1: rain's extinction in the density texture's b channel (rain_params), lit
//                   by the flash's point lights, the sun and the static light's S
//   HAS_RAIN_SOURCE 1 (with HAS_RAIN and HAS_SOURCE): the rain also scatters the flash's light
//                   of orders >= 2 (u_scam's g)
//   TEMPORAL     1: keep the rain's light from the channel apart from the flash's S and
//                   return the ray's opacity-weighted depth (the temporal history's terms)
#ifndef SKIP_EMPTY
#define SKIP_EMPTY 1
#endif
#ifndef EARLY_EXIT
#define EARLY_EXIT 1
#endif
#ifndef HAS_SOURCE
#define HAS_SOURCE 1
#endif
#ifndef HAS_STATIC
#define HAS_STATIC 0
#endif
#ifndef HAS_SUN
#define HAS_SUN 0
#endif
#ifndef HAS_EMISSION
#define HAS_EMISSION 1
#endif
#ifndef HAS_DETAIL
#define HAS_DETAIL 0
#endif
#ifndef HAS_RAIN
#define HAS_RAIN 0
#endif
#ifndef HAS_RAIN_SOURCE
#define HAS_RAIN_SOURCE 0
#endif
#ifndef TEMPORAL
#define TEMPORAL 0
#endif

// r: density rho in [0, 1]; g: Chebyshev (L-infinity) distance, in density voxels / 255,
// from the voxel centre to the nearest voxel with non-zero density or rain (0 inside them);
// b (with rain): the rain's extinction / rain_params.x.
layout(binding = 0) uniform sampler3D u_density;
// S(x, w_cam(x)) on the lighting grid: the source function toward the camera; with
// HAS_RAIN_SOURCE, in g the flash's light of orders >= 2 at the rain toward the camera, per unit
// albedo (pair.comp: one fetch for both).
layout(binding = 1) uniform sampler3D u_scam;
// The static light (sun, moon, sky) toward the camera, rgb, on its grid.
layout(binding = 6) uniform sampler3D u_static;
#ifndef SUN_TRANSMITTANCE_DECLARED
#define SUN_TRANSMITTANCE_DECLARED
// Transmittance from the sun to each full-resolution voxel (the density grid).
layout(binding = 7) uniform sampler3D u_sun_t;
#endif

#if HAS_DETAIL
// The billow field b in [0, 1] on one periodic tile (cloud::DetailNoise): R8, repeat
// wrapping, linear filtering; one period is 1 / detail_params.x metres.
layout(binding = 9) uniform sampler3D u_detail;

// cloud::erode at world point p: rho_d = max(rho - lo, 0) / (1 - lo), lo = strength (1 - b).
// Only removes density, so the undetailed cloud's empty-space distance stays valid.
float detailed_density(float rho, vec3 p) {
    float lo = detail_params.y * (1.0 - textureLod(u_detail, p * detail_params.x, 0.0).r);
    return max(rho - lo, 0.0) / max(1.0 - lo, 1e-6);
}
#endif

// Henyey-Greenstein phase function per steradian (transport::hg_phase).
float hg_phase(float cos_theta, float g) {
    float a = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - cos_theta);
    return (1.0 - g * g) / (4.0 * 3.14159265 * a * sqrt(a));
}

#if HAS_RAIN
// Rain's in-scattered radiance toward the camera (-d) at p, per unit albedo: the channel
// below the rain's top as point lights of equal power (W/sr; the flash colour applied with
// the cloud's flash light), each attenuated by the rain on its way, exp(-m r): r its distance,
// m the rain's mean extinction between p and the lights' centroid (the density texture's
// alpha: render/pass_rain_lights.cpp). r^2 is kept above (50 m)^2: closer, a point stands for
// a stretch of channel, not a point.
// In `light_t` it adds each light's share times its distance along the ray o + t d: the
// rain's forward-scattered halo around a light moves on screen with the light, not with the
// drops that scatter it (the temporal history reprojects it by this; without TEMPORAL the
// sum is not used and compiled away).
//
// Each light's geometry along a ray is taken once per ray (RainRay): with q = o - L, the
// sample at o + t d is at u = t + q.d along the ray from the light's foot and r^2 = u^2 + h^2
// from it (h the ray's distance from the light), and l.(-d) = -u, so a sample costs the
// phase function and no vector arithmetic (the light loop was ~30% of the march with rain).
// RAIN_LIGHTS (compile time): how many of rain_light the march reads, int(rain_lights.x). A
// loop of a count known when compiling is unrolled, the per-ray arrays kept in registers; with
// the count read from the uniform the whole march slowed, even with no light to read (the full
// march with rain at 1280x720 between flashes, 0 lights: 110 -> 84 ms).
#ifndef RAIN_LIGHTS
#define RAIN_LIGHTS 8
#endif
#if RAIN_LIGHTS > 0
#define RAIN_ARRAY RAIN_LIGHTS
#else
#define RAIN_ARRAY 1
#endif

struct RainRay {
    float along[RAIN_ARRAY];  // q.d: the light's foot on the ray is at t = -along
    float h2[RAIN_ARRAY];     // the ray's squared distance from the light
};

RainRay rain_ray(vec3 o, vec3 d) {
    RainRay r;
    for (int i = 0; i < RAIN_LIGHTS; ++i) {
        vec3 q = o - rain_light[i].xyz;
        r.along[i] = dot(q, d);
        vec3 h = cross(q, d);  // not |q|^2 - along^2: that cancels for a far camera
        r.h2[i] = dot(h, h);
    }
    return r;
}

// `mean`: the rain's mean extinction toward the lights over rain_params.x (the density
// texture's alpha).
float rain_flash(RainRay ray, float t, float mean, inout float light_t) {
    float s = 0.0;
    float m = mean * (rain_params.x * 1.4426950);  // times log2(e), for exp2
    for (int i = 0; i < RAIN_LIGHTS; ++i) {
        float u = t + ray.along[i];
        float r2 = max(u * u + ray.h2[i], 2500.0);
        float inv_r = inversesqrt(r2);
        float c = rain_light[i].w * hg_phase(-u * inv_r, rain_params.y) * (inv_r * inv_r) * exp2(-m * (r2 * inv_r));
        s += c;
        light_t -= c * ray.along[i];
    }
    return s;
}

// The rain's optical depth over rain_params.x along the segment p + t l, t in [t0, t1] (none
// when t1 <= t0), by the midpoint rule with one sample per `per_sample` metres of it,
// `max_samples` at most: the paths of the lights' maps (ground_rain.comp, rain_lights.comp).
float rain_depth(vec3 p, vec3 l, float t0, float t1, float per_sample, int max_samples) {
    if (t1 <= t0) return 0.0;
    float len = (t1 - t0) * length(l);
    int n = clamp(int(ceil(len / per_sample)), 1, max_samples);
    float tau = 0.0;
    for (int k = 0; k < n; ++k) {
        vec3 x = p + (t0 + (float(k) + 0.5) / float(n) * (t1 - t0)) * l;
        tau += textureLod(u_density, (x - vol_min.xyz) / vol_size.xyz, 0.0).b;
    }
    return tau * (len / float(n));
}

#endif

// Safety margin of the skip distance, in voxels. The trilinear interpolant D~(p) of the
// distance field satisfies |p - c|_inf >= D~(p) - 1 for every non-zero voxel centre c, and
// the density at q is non-zero only if |q - c|_inf < 1, so a jump of D~ - 2 voxels is exact.
// The extra voxel covers the 8-bit quantization of filtered values (+-0.5) and the
// fixed-point filter weights of software rasterizers.
const float kSkipMargin = 3.0;

vec3 nonzero_dir(vec3 d) {
    return vec3(abs(d.x) < 1e-9 ? 1e-9 : d.x, abs(d.y) < 1e-9 ? 1e-9 : d.y, abs(d.z) < 1e-9 ? 1e-9 : d.z);
}

bool ray_box(vec3 o, vec3 d, vec3 lo, vec3 hi, out float t0, out float t1) {
    vec3 inv = 1.0 / nonzero_dir(d);
    vec3 ta = (lo - o) * inv, tb = (hi - o) * inv;
    vec3 tmin = min(ta, tb), tmax = max(ta, tb);
    t0 = max(max(tmin.x, tmin.y), max(tmin.z, 0.0));
    t1 = min(min(tmax.x, tmax.y), tmax.z);
    return t1 > t0;
}

struct MarchResult {
    float in_scattered;  // integral of T sigma_t S dt (radiance, before the flash colour)
    vec3 in_static;      // the same for the static light and the sun's full-resolution single scattering (rgb)
    float transmittance; // T over the whole ray segment
    float t_emit;        // T from the camera to the emission depth
#if TEMPORAL
    float in_rain_flash; // the rain's in-scattered light from the channel (not in in_scattered)
    float depth;         // opacity-weighted mean distance of the cloud along the ray (0 when it is clear)
    float light_depth;   // the flash's in-scattered light's weighted mean distance (0 when there is none)
    float rain_depth;    // the same for in_rain_flash, by the distance of the lights it scatters
#endif
};

// Integrates L = int T(t) sigma_t(t) S(t) dt over the ray o + t d (d unit) inside the box,
// up to t_end. The chord [t0, t1] is cut at b_k = t0 + (k + jitter) dt (k = 0, 1, ...);
// each piece, clipped to the chord, is sampled at its midpoint with density and S constant
// on it. The pieces cover the chord exactly, so a homogeneous box with constant S gives
// S (1 - exp(-kappa rho chord)) whatever the step, and a linear density is integrated
// exactly (midpoint rule). Boundaries are computed from k, never accumulated, so skipping
// empty pieces leaves the arithmetic of the others bit-identical.
MarchResult march_ray(vec3 o, vec3 d, float t_end, float jitter, float t_emit) {
    MarchResult r;
    r.in_scattered = 0.0;
    r.in_static = vec3(0.0);
    r.transmittance = 1.0;
    r.t_emit = 1.0;
#if TEMPORAL
    r.in_rain_flash = 0.0;
    r.depth = 0.0;
    r.light_depth = 0.0;
    r.rain_depth = 0.0;
#endif
    float t0, t1;
    if (vol_size.w <= 0.0 || !ray_box(o, d, vol_min.xyz, vol_min.xyz + vol_size.xyz, t0, t1)) return r;
    t1 = min(t1, t_end);
    if (t1 <= t0) return r;
    float dt = march_params.x;
    vec3 o_tex = (o - vol_min.xyz) / vol_size.xyz, d_tex = d / vol_size.xyz;
#if HAS_SOURCE
    vec3 o_lit = (o - lit_min.xyz) / lit_size.xyz, d_lit = d / lit_size.xyz;
#endif
#if HAS_STATIC
    vec3 o_st = (o - static_min.xyz) / static_size.xyz, d_st = d / static_size.xyz;
#endif
#if HAS_SUN
    // Single scattering of the sun toward the camera, the exact phase function for this ray
    // (light travelling along sun_dir scattered into -d): albedo p(-d . sun_dir) E x colour.
    vec3 sun_s1 = sun_rgb.w * hg_phase(dot(-d, sun_dir.xyz), sun_params.x) * sun_rgb.rgb;
#endif
#if HAS_RAIN
    RainRay rain = rain_ray(o, d);
#if HAS_SUN
    // What the rain scatters toward the camera (-d) of the sun or moon, per unit albedo: its first
    // scattering through the cloud and the rain (the full-resolution transmittance, read once per
    // sample for the cloud and the rain) with the drops' phase function, constant along the ray.
    float rain_sun_phase = hg_phase(dot(-d, sun_dir.xyz), rain_params.y);
#endif
#endif
    vec3 Ls = vec3(0.0);
    float kappa = vol_min.w;
    float voxel = vol_size.w;
    float T = 1.0, L = 0.0, Te = 1.0;
#if TEMPORAL
    float Lrf = 0.0, depth_sum = 0.0, light_depth_sum = 0.0, rain_depth_sum = 0.0;
#endif
    float a = t0;      // start of the current piece
    float k = 0.0;     // index of its end boundary
    int steps = counts.x;
    for (int i = 0; i < steps; ++i) {
        if (a >= t1) break;
#if EARLY_EXIT
        if (T < march_params.y) break;
#endif
        float b = min(t0 + (k + jitter) * dt, t1);
        float t = 0.5 * (a + b);
        vec4 dv = textureLod(u_density, o_tex + t * d_tex, 0.0);
#if SKIP_EMPTY
        float skip = (dv.g * 255.0 - kSkipMargin) * voxel;
        if (skip >= dt) {
            // Every piece ending before t + skip is empty: continue after the last of them.
            k = floor((t + skip - t0) / dt - jitter);
            a = min(t0 + (k + jitter) * dt, t1);
            k += 1.0;
            continue;
        }
#endif
        float rho = dv.r;
#if HAS_DETAIL
        if (rho > 0.0) rho = detailed_density(rho, o + t * d);
#endif
#if HAS_SUN
        float sun_t = textureLod(u_sun_t, o_tex + t * d_tex, 0.0).r;
#endif
#if HAS_SOURCE
        // S toward the camera; with HAS_RAIN_SOURCE the rain's light in g, from the same fetch.
        // Radiance is never negative: S from the lattice (its signed phase fit) and from
        // truncated Haar coefficients can dip below zero; clamped where it is consumed.
#if HAS_RAIN && HAS_RAIN_SOURCE
        vec2 s_cam = max(textureLod(u_scam, o_lit + t * d_lit, 0.0).rg, vec2(0.0));
#else
        vec2 s_cam = vec2(max(textureLod(u_scam, o_lit + t * d_lit, 0.0).r, 0.0), 0.0);
#endif
#endif
#if HAS_RAIN
        // Cloud and rain in the same piece: alpha from both, each scattering its share.
        float sigma_c = kappa * rho, sigma_r = rain_params.x * dv.b;
        float alpha = 1.0 - exp(-(sigma_c + sigma_r) * (b - a));
        float wc = sigma_c + sigma_r > 0.0 ? sigma_c / (sigma_c + sigma_r) : 0.0;
        float ws = wc;  // the static S's weight: the cloud's share, plus the rain's (HAS_STATIC)
        if (sigma_r > 0.0) {
            float wr = T * alpha * (1.0 - wc) * rain_params.w;
            float light_t = 0.0;
#if TEMPORAL
            Lrf += wr * rain_flash(rain, t, dv.a, light_t);
            rain_depth_sum += wr * light_t;
#else
            L += wr * rain_flash(rain, t, dv.a, light_t);
#endif
#if HAS_RAIN_SOURCE
            // The flash's light that reached the rain after scattering (the lit cloud's light
            // sent down, the rain's own multiple scattering), with the drops' phase function by
            // the cell's share of rain: part of the flash's S, not of the channel's direct light.
            float dR = wr * s_cam.y;
            L += dR;
#if TEMPORAL
            light_depth_sum += dR * t;
#endif
#endif
#if HAS_SUN
            Ls += wr * (sun_rgb.rgb * (rain_sun_phase * sun_t));
#endif
#if HAS_STATIC
            // The static light solved with the rain in its media: S at the rain's points holds
            // the light of every order the cloud and the rain scatter there, the sky's own
            // included, read out with the drops' phase function by the cell's share of rain
            // (transport::PhaseMix); the sun's first scattering is drawn at full resolution with
            // the drops' phase function (rain_sun_phase). S is read once for the cloud and the rain
            // (below), the rain's share per unit albedo.
            ws += (1.0 - wc) * rain_params.w * rain_lights.y;
#endif
        }
#else
        float alpha = 1.0 - exp(-kappa * rho * (b - a));
        const float wc = 1.0;
#endif
#if HAS_SOURCE
#if TEMPORAL
        float dL = T * alpha * wc * s_cam.x;
        L += dL;
        light_depth_sum += dL * t;
#else
        L += T * alpha * wc * s_cam.x;
#endif
#endif
#if HAS_STATIC
#if HAS_RAIN
        Ls += T * alpha * ws * textureLod(u_static, o_st + t * d_st, 0.0).rgb;
#else
        Ls += T * alpha * wc * textureLod(u_static, o_st + t * d_st, 0.0).rgb;
#endif
#endif
#if HAS_SUN
        Ls += (T * alpha * wc * sun_t) * sun_s1;
#endif
#if TEMPORAL
        depth_sum += T * alpha * t;
#endif
        T *= 1.0 - alpha;
#if HAS_EMISSION
        if (t <= t_emit) Te = T;
#endif
        a = b;
        k += 1.0;
    }
    r.in_scattered = L;
    r.in_static = Ls;
    r.transmittance = T;
    r.t_emit = Te;
#if TEMPORAL
    r.in_rain_flash = Lrf;
    // The opacity sum_k T_k alpha_k telescopes to 1 - T.
    r.depth = T < 1.0 ? depth_sum / (1.0 - T) : 0.0;
    r.light_depth = L > 0.0 ? light_depth_sum / L : 0.0;
    r.rain_depth = Lrf > 0.0 ? rain_depth_sum / Lrf : 0.0;
#endif
    return r;
}

// Transmittance from the camera to the point p (same pieces as march_ray, no jitter).
float transmittance_to(vec3 p) {
    vec3 o = cam_pos.xyz;
    vec3 d = p - o;
    float dist = length(d);
    if (dist <= 0.0 || vol_size.w <= 0.0) return 1.0;
    d /= dist;
    float t0, t1;
    if (!ray_box(o, d, vol_min.xyz, vol_min.xyz + vol_size.xyz, t0, t1)) return 1.0;
    t1 = min(t1, dist);
    if (t1 <= t0) return 1.0;
    float dt = march_params.x;
    vec3 o_tex = (o - vol_min.xyz) / vol_size.xyz, d_tex = d / vol_size.xyz;
    float tau = 0.0, tau_rain = 0.0;
    float a = t0, k = 1.0;
    for (int i = 0; i < counts.x; ++i) {
        if (a >= t1) break;
        float b = min(t0 + k * dt, t1);
        float t = 0.5 * (a + b);
        vec4 dv = textureLod(u_density, o_tex + t * d_tex, 0.0);
        float skip = (dv.g * 255.0 - kSkipMargin) * vol_size.w;
        if (skip >= dt) {
            k = floor((t + skip - t0) / dt);
            a = min(t0 + k * dt, t1);
            k += 1.0;
            continue;
        }
        float rho = dv.r;
#if HAS_DETAIL
        if (rho > 0.0) rho = detailed_density(rho, o + t * d);
#endif
#if HAS_SUN
        float sun_t = textureLod(u_sun_t, o_tex + t * d_tex, 0.0).r;
#endif
        tau += rho * (b - a);
#if HAS_RAIN
        tau_rain += rain_params.x * dv.b * (b - a);
#endif
        a = b;
        k += 1.0;
    }
    return exp(-vol_min.w * tau - tau_rain);
}
