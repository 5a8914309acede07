// Shared by every Fulgur shader: the per-frame constants (std140, binding 0; mirrored by
// FrameBlock in engine/render/renderer.cpp) and small helpers. Units: metres, radiance in
// W m^-2 sr^-1. World: z up.

layout(std140, binding = 0) uniform Frame {
    mat4 view_proj;        // world -> clip (rasterized passes)
    vec4 cam_pos;          // xyz camera position, w = tan(vertical fov / 2)
    vec4 cam_fwd;          // xyz unit forward, w = aspect (width / height)
    vec4 cam_right;        // xyz unit right
    vec4 cam_up;           // xyz unit up
    vec4 vol_min;          // xyz density grid lower corner, w = kappa (1/m)
    vec4 vol_size;         // xyz density grid extent, w = density voxel size (0: no volume)
    vec4 lit_min;          // xyz lighting grid lower corner, w = 1 when S is present
    vec4 lit_size;         // xyz lighting grid extent
    vec4 march_params;     // x step (m), y min transmittance, z jitter on, w frame jitter offset
    vec4 sizes;            // xy output size, zw internal (ray-march) size, pixels
    vec4 ground_params;    // x ground height, y albedo / pi, z ground on, w number of ground lights
    vec4 ground_light[8];  // xyz position, w intensity * visibility (W/sr)
    vec4 sky_params;       // x unused, y star radiance, z sky on, w exposure
    vec4 glow_params;      // x glow radius (m), y air scattering (1/m), z glow on, w bolt on
    vec4 light_colour;     // rgb colour of the flash (luminance 1), w dither on
    ivec4 counts;          // x max march steps, y frame index, z glow quads, w bolt segments
    vec4 sky_zenith;       // rgb sky radiance straight up (W m^-2 sr^-1)
    vec4 sky_horizon;      // rgb sky radiance at the horizon; the gradient is mix(horizon, zenith, sqrt(sin el))
    vec4 static_min;       // xyz static light's grid lower corner, w = 1 when the static light is present
    vec4 static_size;      // xyz static light's grid extent
    vec4 sun_dir;          // xyz direction sunlight travels (unit), w = 1 when the sun lights the scene
    vec4 sun_rgb;          // rgb sun irradiance x colour (W m^-2), w = albedo of the cloud
    vec4 sun_params;       // x HG g of the cloud, y = 1 when the full-resolution sun transmittance is bound,
                           // z = 1 when the sun's first scattering is drawn in the volume (cloud and rain)
    vec4 host_depth;       // a host's depth buffer: x P22, y P32 of its projection (eye depth = y / (z_ndc + x)),
                           // z 1 when its depth is in [0, 1] (else [-1, 1]), w 0 none, 1 standard Z, -1 reversed Z
    vec4 detail_params;    // sub-voxel detail: x 1 / tile period (1/m), y erosion strength
    vec4 rain_params;      // rain: x extinction at b = 1 (1/m), y HG g, z its top (m), w albedo
    vec4 rain_light[8];    // the channel below the rain's top as point lights: xyz position, w W/sr
    vec4 rain_lights;      // x number of rain_light (0 when the flash does not light the volume),
                           // y 1 / the cloud's albedo (which the static S carries), z the share of
                           // the rain's extinction on the ground lights' way (render::VolumeDesc::rain_solved_share)
    vec4 ground_scatter;   // the cloud's scattered flash light on the ground (u_ground_scatter):
                           // xy lower corner of its cells (m), zw 1 / its extent along x, y (1/m); zw 0: none
    vec4 ground_static;    // the static light on the ground (u_ground_static), as ground_scatter
};

// The host's depth buffer (render_into_host), full output resolution; read only when host_depth.w != 0.
layout(binding = 8) uniform sampler2D u_host_depth;

const float kBig = 1e30;

float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// Camera ray through a point of the image plane given in NDC ([-1, 1]^2, y up).
// cam_right.w and cam_up.w shift the image centre (an off-centre projection's lens shift, NDC).
vec3 camera_ray(vec2 ndc) {
    ndc += vec2(cam_right.w, cam_up.w);
    return normalize(cam_fwd.xyz + ndc.x * cam_pos.w * cam_fwd.w * cam_right.xyz + ndc.y * cam_pos.w * cam_up.xyz);
}

// The host's opaque surface at an output pixel as an eye depth (distance along the view axis,
// metres); kBig where it holds its clear value (nothing opaque) or there is no host depth.
float host_eye_depth(vec2 pixel) {
    if (host_depth.w == 0.0) return kBig;
    float z = texelFetch(u_host_depth, ivec2(pixel), 0).r;
    if (host_depth.w > 0.0 ? z >= 1.0 : z <= 0.0) return kBig;
    float z_ndc = host_depth.z > 0.5 ? z : 2.0 * z - 1.0;
    float eye = host_depth.y / (z_ndc + host_depth.x);
    return eye > 0.0 ? eye : kBig;
}

// Interleaved gradient noise (Jimenez 2014): a per-pixel value in [0, 1) whose neighbours
// differ strongly (blue-noise-like), so jittered sampling leaves fine noise, not banding.
float interleaved_gradient_noise(vec2 pixel) {
    return fract(52.9829189 * fract(dot(pixel, vec2(0.06711056, 0.00583715))));
}

// 32-bit integer hash (Jarzynski & Olano 2020, PCG-based), deterministic on every GPU.
uint hash_u32(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}
uint hash_u32(uvec3 v) { return hash_u32(v.x ^ hash_u32(v.y ^ hash_u32(v.z))); }
float hash_unit(uint h) { return float(h >> 8) * (1.0 / 16777216.0); }

// Distance along the ray to the ground plane (kBig when the ray does not hit it or the
// ground is off).
float ground_distance(vec3 o, vec3 d) {
    if (ground_params.z < 0.5 || d.z >= -1e-6 || o.z <= ground_params.x) return kBig;
    return (ground_params.x - o.z) / d.z;
}
