// fulgur::render — the OpenGL 4.5 core renderer: storm cloud volume, bolt, glow, sky, ground.
//
// The renderer draws into whatever framebuffer is bound when render() is called, in a GL
// 4.5 core context that is current on the calling thread; it loads GL functions through the
// get-proc-address of that context (glad2). It never creates contexts or windows (see
// app/platform). Inputs are plain structs; the renderer does not know about bakes, bolts'
// generators or scenes.
//
// Physics (docs/design.md#source-function): sigma_t(x) = kappa * rho(x) from the full-resolution density;
// S(x, s) is the source function (radiance scattered INTO direction s) on the lighting grid,
// for the baked output directions (transport::output_directions order). The camera sees
//     L_cam = integral_0^D T(0, t) sigma_t(x_t) S(x_t, w_cam(x_t)) dt + T(0, D) L_background
// with w_cam(x) = normalize(camera - x) (from the sample toward the camera), plus the bolt
// core and its glow attenuated by the cloud in front of them. docs/render.md describes the
// passes, the direction interpolation, the tone map and measured timings.
//
// Frame outline (one call to render()):
//   resolve   S_cam(x_i) = sum_m w_m(normalize(camera - x_i)) S_m(x_i) on the lighting grid
//             (compute shader; only when S or the camera changed; skipped for 1 direction)
//   glow      texture-mapped glow quads along the strokes -> emission buffer (internal res)
//   march     ray march at internal resolution -> (in-scattered + attenuated glow, T); first,
//             with rain, the rain's transmittance toward each ground light on a map (compute,
//             made when the lights or the rain change)
//   bolt      bright HDR core ribbons at full resolution, attenuated per vertex
//   meter     (automatic exposure) a luminance histogram of the march, read back
//   composite upsample + background (sky, stars, ground) * T + bolt -> filmic tone map
//
// Besides the flash's S (grey; the flash colour tints it) the march draws the static light,
// S of the sun (or moon) and the sky in colour (upload_static), and the sun's single
// scattering at full resolution from its transmittance through the full-resolution density
// (set_sun): the silver lining where the view looks toward the sun.
#pragma once

#include "cloud/rain.h"
#include "cloud/subvoxel.h"
#include "core/core.h"
#include "transport/directions.h"

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace fulgur::render {

/// GL function pointer and a context's get-proc-address (glad's GLADapiproc/GLADloadfunc).
using GLProc = void (*)();
using GetProcAddress = GLProc (*)(const char* name);

/// The shader directory: $FULGUR_SHADER_DIR when set, else the source tree's shaders/ when it
/// exists, else the installed <prefix>/share/fulgur/shaders (both fixed at compile time; an
/// installed package moved elsewhere passes Fulgur_SHADER_DIR from its CMake config).
std::filesystem::path default_shader_dir();

// ---------------------------------------------------------------------------------------
// Inputs

/// Storage precision of the density texture (an accuracy/time knob, measured by
/// `fulgur-bench render`). U8 quantizes rho to 1/255 (error <= 0.002 in rho);
/// F16 keeps ~3 significant digits.
enum class DensityPrecision { U8, F16 };

/// The cloud: density at full resolution and the extinction per unit density.
struct VolumeDesc {
    const core::Grid3<float>* density = nullptr;  ///< rho in [0, 1] (values outside are clamped)
    double extinction = 0.02;                     ///< kappa (1/m): sigma_t = kappa * rho
    DensityPrecision precision = DensityPrecision::U8;
    /// Sub-voxel detail eroded into `density` at every ray-march sample (cloud/subvoxel.h):
    /// then `density` is the cloud before its detail (scene::make_undetailed_density), and
    /// the march draws cloud::detailed_at. None: the density as given, no detail texture.
    std::optional<cloud::SubvoxelDetail> detail = std::nullopt;
    /// Rain on the density grid (cloud::make_rain), drawn with the cloud: its extinction, its
    /// light (the flash's point lights, the sun through set_sun's transmittance, the sky) and
    /// its shadow on the ground's flash light. Null (or no rain in it): none, no cost.
    const cloud::RainField* rain = nullptr;
    /// The share of the rain's extinction the flash's light solves carry, > 0. The ground's
    /// flash lights are attenuated by that share on their way through the rain, so that their
    /// light and the solved light the rain scatters onto the ground (Frame::ground) are one
    /// medium's. A lattice carries the rain as cloud of equal transport coefficient
    /// (sky::rain_media_density x kappa; 0.39 for the default storm's drops and cloud): with the
    /// full extinction the light the drops scatter forward was lost, and the ground under a
    /// shaft too dark (docs/blender.md). 1: the rain's full extinction, as Monte Carlo paths
    /// carry it (transport::PathMix). set_rain_solved_share() changes it alone.
    double rain_solved_share = 1.0;
};

/// One upload of the source function S. Only the listed directions are transferred. By
/// default the listed directions *replace* S: the current S is exactly the set listed in the
/// latest upload, and other directions count as absent (if the view needs one, it contributes
/// zero and FrameStats::missing_weight reports it). With `keep_others`, directions not listed
/// keep their previous data, so a caller can upload only what changed (e.g. a direction a
/// moved camera now needs while S itself is unchanged); a different geometry or direction
/// count still starts from an empty set.
struct SourceUpload {
    core::GridGeometry geometry;  ///< lighting grid (world placement of the S samples)
    int direction_count = 1;      ///< size of the baked set: 1, 6, 18 or 26
    std::vector<int> directions;  ///< indices into transport::output_directions(direction_count)
    /// One array per listed direction: geometry.cell_count() floats, x fastest
    /// (transport::SourceField layout), radiance units. Must stay valid during the call only.
    std::vector<std::span<const float>> values;
    bool keep_others = false;
};

/// The static light: S of the sun (or moon) and the sky in colour, on a lighting grid, for
/// every direction of the baked set (it changes only when the sun moves). With rain (VolumeDesc::
/// rain) S is that of the static light solved with the rain in its media (sky::static_media), and
/// the rain's samples scatter it too, times the rain's albedo / `albedo`.
struct StaticUpload {
    core::GridGeometry geometry;
    int direction_count = 1;  ///< 1, 6, 18 or 26 (transport::output_directions order)
    double albedo = 0.99;     ///< the cloud's single-scattering albedo, which S carries, [0, 1]
    /// One array per direction (all of them, in order): 3 floats (rgb) per cell, x fastest,
    /// radiance units. Must stay valid during the call only.
    std::vector<std::span<const float>> rgb;
    /// The static light on the ground besides the sun's direct beam (sky::compose_ground): the
    /// light the cloud scatters down and the sky seen past the cloud, irradiance in colour
    /// (W/m^2, 3 floats per cell) on square cells of the ground plane, x fastest. It takes the
    /// place of the sky's unshadowed irradiance, pi (0.2 horizon + 0.8 zenith), on its cells;
    /// empty (or outside them): that. Must stay valid during the call only.
    struct Ground {
        glm::dvec2 origin{0.0};  ///< lower corner (x, y) of cell (0, 0), metres
        double cell = 0.0;       ///< cell size (m), > 0
        int nx = 0, ny = 0;      ///< cells along x and y, each in [1, 4096]
        std::span<const float> rgb;
    } ground;
};

/// The sun drawn at full resolution: its single scattering
///   S1(x, w_cam) = albedo p_HG(w_cam . direction; g) E T_sun(x)   (rgb: E x colour)
/// with T_sun from the sun to x through the full-resolution density (`transmittance`, on
/// set_volume()'s grid), and the ground's sunlight with the cloud's shadow. Without
/// `transmittance` only the ground is lit (the static light then carries the cloud's).
struct SunDesc {
    glm::dvec3 direction{0.0, 0.0, -1.0};               ///< the direction sunlight travels
    glm::dvec3 irradiance_rgb{0.0};                     ///< E x colour, W m^-2 per channel
    double albedo = 0.99, g = 0.0;                      ///< the cloud's single-scattering albedo and HG g
    const core::Grid3<float>* transmittance = nullptr;  ///< values in [0, 1]; copied
    bool scatter = true;  ///< draw its single scattering in the cloud (false: the ground's light only)
};

/// A straight piece of lightning channel at this instant.
struct ChannelSegment {
    glm::vec3 a{0.0f}, b{0.0f};  ///< endpoints (metres, world)
    float intensity = 0.0f;      ///< radiant intensity per metre of channel (W sr^-1 m^-1), >= 0
    float radius = 1.0f;         ///< channel radius (m): core radiance = intensity / (2 radius)
};

/// What the renderer draws of the lightning this frame: the lit stretches of channel with their
/// instant intensity (the view builds it from lightning::LitSegment). Not lightning::Bolt,
/// which is a bolt's whole geometry over its flash.
struct LitChannel {
    std::vector<ChannelSegment> segments;
    /// The light the cloud scatters onto the ground at this instant (runtime::Frame::ground):
    /// irradiance in W/m^2 (at the flash's colour of luminance 1) averaged over square cells of
    /// the ground plane, x fastest. The channel's own light on the ground (its point lights,
    /// flash_lights()) is apart. Empty: none (the ground is lit by the channel alone).
    struct GroundScatter {
        glm::dvec2 origin{0.0};  ///< lower corner (x, y) of cell (0, 0), metres
        double cell = 0.0;       ///< cell size (m)
        int nx = 0, ny = 0;      ///< cells along x and y
        std::vector<float> irradiance;
    } ground;
};

struct Camera {
    glm::dvec3 position{0.0, -30000.0, 3000.0};
    glm::dvec3 target{0.0, 0.0, 4000.0};
    glm::dvec3 up{0.0, 0.0, 1.0};
    double vertical_fov_deg = 50.0;
    /// An off-centre projection's shift of the image centre in NDC (a host's jittered or
    /// asymmetric projection: its projection[2][0] and [2][1]); 0 for a centred view.
    glm::dvec2 lens_shift{0.0};

    /// Camera on a sphere around `target`: azimuth from +x toward +y, elevation above the
    /// horizontal plane (degrees).
    static Camera orbit(const glm::dvec3& target, double distance, double azimuth_deg, double elevation_deg,
                        double vertical_fov_deg = 50.0);
};

/// Default of Settings::direction_min_weight and of the `min_weight` arguments of
/// view_directions() and Renderer::needed_directions().
inline constexpr double kDirectionMinWeight = 1e-3;

/// A host engine's frame the storm is composited into (Renderer::render_into_host).
struct HostFrame {
    glm::dmat4 view{1.0};        ///< world -> eye (OpenGL's convention: the camera looks down -z, +y up)
    glm::dmat4 projection{1.0};  ///< eye -> clip: perspective, centred or off-centre, finite or infinite far plane
    /// The host's depth buffer as a GL texture of the output's size (GL_DEPTH_COMPONENT*; read
    /// with comparison off, whatever its own mode), written with `projection`; 0: nothing opaque.
    unsigned depth_texture = 0;
    bool depth_zero_to_one = false;  ///< glClipControl's GL_ZERO_TO_ONE depth (else GL's [-1, 1])
    bool reversed_z = false;         ///< depth 1 at the near plane, 0 far (its clear value: nothing there)
};

/// The Camera a host's view and projection matrices describe (position, target one metre ahead,
/// up, vertical field of view, lens shift). Throws core::Error naming the matrix and entry when
/// `projection` is not a perspective projection (w = -z_eye) or `view` is not a rigid motion,
/// or the projection's aspect ratio differs from `aspect` (the target's width / height) by more
/// than 0.1%.
Camera camera_from_matrices(const glm::dmat4& view, const glm::dmat4& projection, double aspect);

enum class MarchKernel { Fragment, Compute };

/// How the temporal history fills the pixels a moving camera does not march
/// (Settings::temporal_light): every light group (the flash's, the channel's and the cloud's,
/// with its transmittance) reprojected from the history through its depth, or upsampled from
/// this frame's marched pixels. Against a fresh render of each frame, orbiting the synthetic
/// storm with a 55 degree field (docs/render.md, "Temporal history"): upsampled is the more
/// accurate where the marched pixels are close together on screen (at 1280x720, every other
/// internal pixel 0.31 degrees apart, during a flash: the light 2.3% / 9.4% against 3.9% /
/// 12.8%, plain / detail and rain; between flashes 0.6% / 1.2% against 1.1% / 1.9%, and ~5 ms
/// less of the resolve), reprojected where they are far apart (at 640x360, 0.61 degrees: the
/// light 4.5% / 12.2% against 7.3% / 16.4%).
enum class TemporalLight {
    Auto,       ///< Upsample when every other internal pixel is at most kTemporalUpsampleDeg apart, else Reproject
    Reproject,  ///< from the history, each group through its depth (where the history saw it)
    Upsample,   ///< bilinearly from this frame's marched pixels, every group
};

/// The angle (degrees, vertically) between every other internal pixel at or below which
/// TemporalLight::Auto upsamples, a quarter or a sixteenth marched alike: between the two
/// measured internal resolutions, 0.31 (1280x720 at a 55 degree field: upsampling better, a
/// quarter and a sixteenth) and 0.61 (640x360: reprojecting better in radiance), at their
/// geometric mean. A sixteenth's marched pixels are twice as far apart, but its history is four
/// times older: at 1280x720 its frames upsampled are the nearer a fresh render too (3.3% against
/// 4.0%; docs/render.md).
inline constexpr double kTemporalUpsampleDeg = 0.44;

/// Whether a moving camera's frame upsamples its pixels not marched (true) or reprojects them:
/// `mode`, and for Auto the angle between every other pixel of a march `march_height` pixels
/// high over `vertical_fov_deg`.
constexpr bool temporal_upsamples(TemporalLight mode, double vertical_fov_deg, int march_height) {
    if (mode != TemporalLight::Auto) return mode == TemporalLight::Upsample;
    return march_height > 0 && 2.0 * vertical_fov_deg / double(march_height) <= kTemporalUpsampleDeg;
}
/// The angle (degrees, vertically) between every fourth internal pixel at or below which
/// Settings::temporal_moving_block 0 (auto) marches a sixteenth between flashes, else a quarter:
/// up to the spacing measured at 1280x720 with a 55 degree field (0.61 degrees; orbiting with
/// detail and rain a fresh render's frame is 3.3% / 0.13 display levels away, against the
/// quarter's 1.2% / 0.04 and the default flash frame's 8.9% / 0.13, for 17 instead of 28 ms;
/// 1920x1080, 0.41 degrees: 2.0% / 0.07). At 640x360 (1.22 degrees) a sixteenth's frame is
/// 5.2% / 0.52 levels away for 8.3 instead of 10.7 ms: the quarter kept (docs/render.md).
inline constexpr double kTemporalSixteenthDeg = 0.62;

/// The block of which a moving camera between flashes marches one pixel a frame: `setting`
/// (Settings::temporal_moving_block) if 2 or 4, and for 0 (auto) 4 where every fourth pixel of
/// a march `march_height` pixels high over `vertical_fov_deg` is at most kTemporalSixteenthDeg
/// apart, else 2.
constexpr int temporal_block(int setting, double vertical_fov_deg, int march_height) {
    if (setting != 0) return setting;
    return march_height > 0 && 4.0 * vertical_fov_deg / double(march_height) <= kTemporalSixteenthDeg ? 4 : 2;
}

/// What a frame of the temporal history marches when a light group changed in shape (a leader's
/// front growing, another stroke or branch lighting, a strike's own solve replacing its first
/// light) while the cloud's group still holds (Settings::temporal_reshape).
enum class TemporalReshape {
    /// A quarter of the pixels (one of each 2x2 block, as a moving camera): the groups that
    /// changed are upsampled from them, the cloud's group (its transmittance and the static
    /// light) kept from the history, in place for a still camera. A still camera then marches
    /// the other quarters in turn once the shapes hold, after which its history is exact again.
    Quarter,
    Full,  ///< every pixel, every group: each frame exactly a fresh render's, at a fresh render's cost
};

/// What the temporal history did in a frame (Settings::temporal).
enum class TemporalStep {
    Off,      ///< no history: the march as without it
    Full,     ///< every pixel marched (no history yet, or a light changed in shape)
    Quarter,  ///< the camera moved: a quarter of the pixels marched (between flashes a sixteenth
              ///< where Settings::temporal_moving_block picks 4), the rest filled
    Reused,   ///< a still camera and lights changed only in intensity: nothing marched
};
enum class Timing { Off, Finish, Queries };

/// The ground's look (background.glsl's ground_albedo and ground_haze), one set of constants
/// for the shaders (written into each as GROUND_* defines) and for a frame exported to another
/// renderer (fulgur-shot --blender). At a ground point (x, y) the albedo is
///   Settings::ground_albedo x (low + span v(x / cell_m, y / cell_m)) x tint_rgb,
/// v the value noise of the cell corners' hashes (hash_unit(hash_u32(uvec3(i, j, seed))),
/// common.glsl) blended by smoothstep: fields 1.5 km across, mean 1 x tint. Seen from the
/// camera at a distance t the ground's radiance is mixed toward the sky's horizon radiance
/// (black with the sky off) by 1 - exp(-t / haze_m): aerial perspective.
struct GroundLook {
    static constexpr double cell_m = 1500.0;
    static constexpr unsigned seed = 7;
    static constexpr double low = 0.85, span = 0.3;
    static constexpr std::array<double, 3> tint_rgb{0.9, 1.0, 0.85};
    static constexpr double haze_m = 40000.0;
};

/// Frame settings. Every accuracy/time knob is here with its default.
struct Settings {
    // Image
    /// Automatic exposure (docs/render.md "Exposure"): each frame meters its ray march and
    /// maps its log-average luminance to a key that keeps dim scenes dim, lowered so that at
    /// most highlight_fraction of the lit pixels lie above the tone curve's shoulder (the
    /// display's white is reached by far fewer). false: `exposure`.
    bool auto_exposure = false;
    double exposure = 1.0;               ///< manual exposure: linear multiplier before the tone map
    double exposure_compensation = 0.0;  ///< stops added to the automatic exposure
    double highlight_fraction = 0.02;    ///< lit pixels the automatic exposure lets above its highlight level
    /// Eye adaptation (automatic exposure): the previous frame's exposure (0: none, the metered
    /// one applies at once) and the seconds since; the exposure moves toward the metered one
    /// in log space with these time constants (0: at once).
    double previous_exposure = 0.0, adaptation_seconds = 0.0;
    double brighten_seconds = 1.5, darken_seconds = 0.0;
    /// The automatic exposure's histogram counts one ray-march pixel of each meter_stride x
    /// meter_stride block (1: every pixel, 1..8). The exposure is chosen from the histogram's
    /// log-average and a percentile, statistics a quarter of the pixels estimates closely (on
    /// the demo's frames within a fraction of a quarter-stop bin: docs/render.md "Exposure"),
    /// and the pass costs a quarter.
    int meter_stride = 2;
    double internal_scale = 0.5;  ///< ray-march resolution / output resolution, (0, 1]
    bool dither = true;           ///< +-0.5 LSB triangular dither before 8-bit output (no banding)
    // Ray march
    double step_voxels = 1.0;         ///< step length in density voxels (accuracy/time knob)
    bool jitter = true;               ///< per-pixel start offset (interleaved gradient noise + R1 per frame)
    bool skip_empty = true;           ///< empty-space skipping (Chebyshev distance field)
    bool early_exit = true;           ///< stop when the transmittance falls below min_transmittance
    double min_transmittance = 1e-3;  ///< early-exit threshold (max error: this * S along the rest)
    MarchKernel kernel = MarchKernel::Fragment;
    /// The temporal history (docs/render.md, "Temporal history"): the march keeps its light
    /// per group (the flash's S, the channel's direct light, the static light) with the
    /// transmittances and a depth. A frame whose groups changed only in intensity rescales
    /// the history: a still camera marches nothing, a moving one a quarter of the pixels (a
    /// 2x2 block's pixels in turn) and fills the rest from the history reprojected through
    /// their depth or from the marched pixels (temporal_light). The flash or the channel in a
    /// new shape (a leader's front, another strike) marches a quarter and upsamples them
    /// (temporal_reshape; or every pixel); a new static light, any other input or setting marches
    /// every pixel. The fragment kernel; not with render_into_host.
    bool temporal = false;
    /// With the temporal history: what a frame marches when the flash's or the channel's light
    /// changed in shape (docs/render.md, "A light that changes in shape").
    TemporalReshape temporal_reshape = TemporalReshape::Quarter;
    /// With the temporal history and a moving camera: how the pixels not marched are filled
    /// (every light group and the cloud's transmittance alike).
    TemporalLight temporal_light = TemporalLight::Auto;
    /// With the temporal history and a moving camera: one pixel of each N x N block is marched
    /// per frame, the rest filled (temporal_light). 2: a quarter, every pixel fresh every 4
    /// frames. 4: a sixteenth between flashes (no flash S, no channel), every 16 frames, and a
    /// quarter during a flash (at 1280x720 orbiting with detail and rain, between flashes 17.4 ms
    /// and 3.3% from a fresh render against the quarter's 28 ms and 1.2%; during a flash a
    /// sixteenth erred by 24%, 0.72 levels of 255 as displayed against 0.16: docs/render.md).
    /// 0 (auto): 4 where the sixteenth's marched pixels are close together on screen
    /// (temporal_block, kTemporalSixteenthDeg: 1280x720 and above at a 50-55 degree field),
    /// else 2. A camera that stops marches its quarters in turn either way.
    int temporal_moving_block = 0;
    /// With the temporal history and a moving camera, while a flash or channel lights the frame:
    /// 2 a quarter marched (the default), 4 a sixteenth where temporal_moving_block marches one
    /// between flashes (its rule for 0). The sixteenth trades the edges of the lit cloud for time:
    /// at 1280x720 orbiting through a return stroke with detail and rain 39 -> 25 ms a frame, and
    /// 7.4% -> 13% from a fresh render, 0.11 -> 0.32 levels of 255 as displayed, 0.6% -> 2.8% of
    /// the pixels over 2 levels, in steps along the cloud's lit silhouette (docs/render.md). A
    /// light that changes in shape still marches a quarter.
    int temporal_flash_block = 2;
    std::uint32_t frame_index = 0;  ///< varies the jitter pattern between frames (deterministic)
    // Effects
    bool sky = true;
    bool ground = true;
    /// The ground lit by the cloud's scattered flash light (LitChannel::ground), when given.
    bool ground_scatter = true;
    bool bolt = true;
    bool glow = true;
    bool cloud_lighting = true;  ///< false: S = 0 (cloud only absorbs the background)
    bool flash_light = true;     ///< the flash's S (false: not sampled, no resolve)
    bool static_light = true;    ///< the static light's S (sun, moon, sky; false: not sampled, no resolve)
    bool sun_light = true;       ///< the sun at full resolution and on the ground (false: not drawn)
    /// The volume's sub-voxel detail (VolumeDesc::detail) in the march; false: the undetailed
    /// density is drawn (no detail texture fetch). No effect without detail.
    bool detail = true;
    /// With the detail drawn, the march step is at most this many of its finest billows
    /// (scale / 2^(octaves - 1)); 0: step_voxels alone. 2 keeps the march within 1% of a
    /// step-0.25 reference where step 1 errs by 1.3% (docs/render.md, `fulgur-bench render`).
    double detail_step_billows = 2.0;
    /// The volume's rain (VolumeDesc::rain); false: not drawn (the texture keeps it).
    bool rain = true;
    /// With rain and the ground lit by the channel: the rain's transmittance between the ground
    /// and each ground light is tabulated once per channel on a polar map around the light's
    /// foot (integrated a sample per density voxel), and the ground reads one value per light;
    /// false: every ground pixel integrates each path by 4 samples. docs/render.md, "Bolt,
    /// glow, ground, sky", has what either costs and how far each is from a finer integral.
    bool ground_rain_map = true;
    // Scene constants
    double ground_height = 0.0;  ///< z of the ground plane (m)
    double ground_albedo = 0.1;  ///< mean Lambertian reflectance of the ground (wet fields at night; GroundLook)
    /// Colour of the flash (luminance ~1; bluish white: lightning's spectrum is dominated
    /// by nitrogen and hydrogen lines) applied to S, the bolt, the glow and the ground light.
    glm::dvec3 flash_colour{0.93, 0.97, 1.25};
    int ground_lights = 6;  ///< representative point lights along the bolt for the ground
    /// The sky behind the cloud (rgb radiance, W m^-2 sr^-1): mix(horizon, zenith, sqrt(sin
    /// elevation)), the scene's sky dome; default: a dark night sky (airglow, greyer at the horizon).
    glm::dvec3 sky_zenith{9e-8, 1.2e-7, 2e-7};
    glm::dvec3 sky_horizon{4.8e-7, 4.6e-7, 5.2e-7};
    double star_radiance = 2e-5;  ///< brightest stars (W m^-2 sr^-1, per pixel-sized star)
    /// The stars and the channel's core drawn over the composite without them, the stars as
    /// points and the core as its ribbons widened by 2 pixels, each pixel they cover shaded by the
    /// whole composite: only the pixels near a star find its cell and only those near the core
    /// read it (the same frame to the bit; at 1280x720 the stars ~0.5 ms instead of ~3, the core
    /// ~2.3 ms less during a flash). false: every pixel computes its stars and reads the core (the
    /// reference the overlays are tested against). Views too wide for GL's largest point (~130
    /// degrees) compute every pixel's stars either way; a host's frame reads the core everywhere.
    bool composite_overlays = true;
    /// The march's frame (its radiance and glare) tone mapped at the march's resolution and
    /// upsampled as display values (sRGB), as games upsample after their tone map; the pixels
    /// the channel's core and the stars light are tone mapped at the output's resolution. At
    /// 1280x720 from 640x360 the composite takes ~3 ms less; the frame differs from the
    /// radiance upsampled before the tone map (false) only where the march's texels differ
    /// steeply (render.md, "HDR, tone map, upsampling"). The radiance read back (read_hdr,
    /// render_linear) and a host's frame are upsampled as radiance either way; so is every
    /// pixel when the march runs at the output's resolution.
    bool display_upsample = true;
    double air_scattering = 1.5e-5;  ///< sigma_s of the (rainy) air around the bolt (1/m): glow strength
    double glow_radius = 600.0;      ///< glow quad radius (m); the profile tapers to 0 there
    double bolt_min_width_px = 1.5;  ///< thinner ribbons are widened and dimmed (flux conserved)
    /// The eye's glare around the channel (glare_psf, Spencer et al. 1995): the frame's light
    /// spread by P through a pyramid (GlareFit), energy conserving, so a channel 10^4-10^6
    /// times the cloud veils its surround while an even area keeps its radiance. Runs only in
    /// frames that draw the channel (bolt on, lit segments); off: no pass, the same pixels.
    bool glare = false;
    /// Directions with smaller interpolation weights are not needed (see view_directions);
    /// 0 uses every direction with a non-zero weight.
    double direction_min_weight = kDirectionMinWeight;
    Timing timing = Timing::Finish;
};

/// A baked output direction the current view needs, with the largest interpolation weight it
/// receives anywhere in the (non-empty part of the) lighting grid.
struct DirectionUse {
    int index = 0;
    double max_weight = 0.0;
};

/// The interpolation of S between the baked directions the renderer resolves with
/// (transport/directions.h).
using transport::direction_weights;
using transport::DirectionWeights;

/// The directions S must provide for a camera at `camera_position`: the directions whose
/// weight direction_weights(normalize(camera - x_i)) exceeds `min_weight` at some
/// lighting-grid node x_i with `active[i] != 0` (all nodes when `active` is empty), sorted
/// by index. Directions below the threshold are left out (the smooth weights give every
/// neighbouring direction a tiny weight); the resolve renormalizes the weights of the
/// directions it has, so leaving them out changes S by less than min_weight times the
/// spread of S over the directions.
std::vector<DirectionUse> view_directions(const glm::dvec3& camera_position, const core::GridGeometry& lighting,
                                          int direction_count, std::span<const std::uint8_t> active = {},
                                          double min_weight = kDirectionMinWeight);

/// Samples a plain fixed-step ray march of `volume` takes for this view (sum over the pixels
/// of an internal-resolution image of chord / step): the unit behind samples/s figures.
double plain_march_samples(const Camera& camera, const core::GridGeometry& volume, int width, int height,
                           double step_metres);

// ---------------------------------------------------------------------------------------
// Glare

/// The eye's glare: the photopic point-spread function of Spencer et al. 1995 (Eqs. 4-7),
///   P(theta) = 0.384 f0 + 0.478 f1 + 0.138 f2,     theta in degrees,
///   f0 = 2.61e6 exp(-(theta / 0.02)^2),  f1 = 20.91 / (theta + 0.02)^3,  f2 = 72.37 / (theta + 0.02)^2,
/// per steradian: f0 and f1 each hold one unit of energy over the sphere, f2 (its log tail)
/// reaches one unit at ~80 degrees. The scattering in the cornea, lens and retina that makes a
/// source far brighter than its surround veil them: what a display cannot show by luminance,
/// the renderer adds as the veil (Settings::glare).
double glare_psf(double theta_deg) noexcept;
/// The fraction of a point's light P puts within `theta_deg` of it (closed form; small angles,
/// dOmega = 2 pi theta dtheta).
double glare_energy_within(double theta_deg) noexcept;

/// P approximated by the renderer's glare pyramid, which starts at the ray march's resolution:
/// a frame keeps `keep` of its light in place (P's energy within half a ray-march pixel: the
/// core of f0 and f1) and spreads the rest by a sum of Gaussians, one per pyramid level (sigma
/// doubling per level), with non-negative weights fitted to P's energy-within-radius curve
/// from one ray-march pixel to `reach_deg` (the frame's half diagonal: light P sends farther
/// leaves the frame).
struct GlareFit {
    double keep = 1.0;
    std::vector<double> weights;   ///< per level
    std::vector<double> sigma_px;  ///< per level: the Gaussian's width in internal (ray-march) pixels
    double reach_deg = 0.0;
    double max_error = 0.0;  ///< largest |model - P| of the energy within a radius, over the fitted radii
};
/// The fit for a frame whose output pixels span `output_pixel_deg` and whose ray march runs at
/// `internal_scale` of the output resolution, with `levels` pyramid levels (>= 1).
GlareFit fit_glare(double output_pixel_deg, double internal_scale, int levels, double reach_deg);
/// The Gaussian width (internal pixels) of pyramid level k's contribution: the variance of its
/// box downsamples, tent upsamples and bilinear resampling (docs/render.md, "Glare").
double glare_level_sigma(int k) noexcept;
/// Upsampling onto levels from this one on uses nine taps a coarser texel either side (a
/// smoother tent: the coarse levels' texels are large on screen); finer levels four taps.
inline constexpr int kGlareWideFrom = 2;

// ---------------------------------------------------------------------------------------
// Display

/// The composite's display transform (shaders/tonemap.glsl) on the CPU, without the dither:
/// `radiance` (linear sRGB, W m^-2 sr^-1) times `exposure` through the ACES filmic fit, sRGB
/// encoded by the shader's own approximation of the power, as 8-bit levels (0-255, rounded).
/// To compare frames as a viewer sees them: two radiance images at the same exposure
/// (fulgur-bench render's display errors). Within a level of the composite's output
/// (test_render_images: float32 against double).
std::array<int, 3> display_levels(const glm::dvec3& radiance, double exposure) noexcept;

// ---------------------------------------------------------------------------------------
// Output

/// Times of one frame's passes, milliseconds (0 for passes that did not run).
struct PassTimes {
    double upload = 0;   ///< S uploads since the previous frame (time of the upload calls)
    double resolve = 0;  ///< S toward the camera (only when S or the camera changed)
    double glow = 0;
    double march = 0;
    double meter = 0;      ///< exposure metering (automatic exposure only)
    double bolt = 0;       ///< endpoint transmittances + core ribbons
    double glare = 0;      ///< the glare pyramid (frames that draw the channel with Settings::glare)
    double composite = 0;  ///< upsampling, background, tone map
    double total = 0;      ///< the whole render() call
};

/// Statistics of the last frame. With Timing::Finish each pass ends with glFinish and is
/// timed twice: `wall` on the steady clock, `cpu` as the process CPU time over the pass
/// (with a software rasterizer: the work of all its threads; unlike wall time it does not
/// grow when other processes compete for the cores). Timing::Queries fills `wall` from GL
/// timer queries (render() waits for them); Timing::Off only measures `total` (no glFinish).
struct FrameStats {
    PassTimes wall, cpu;
    int internal_width = 0, internal_height = 0;
    int directions_used = 0;      ///< directions with non-zero weight in this view
    double missing_weight = 0.0;  ///< largest weight of a needed direction that was not uploaded
    int glow_quads = 0, bolt_segments = 0;
    double exposure = 0.0;          ///< the exposure the frame was tone mapped with
    double metered_exposure = 0.0;  ///< what the automatic exposure called for (0: manual)
    double glare_keep = 1.0;        ///< the share of the frame's light the glare left in place (1: no glare)
    TemporalStep temporal = TemporalStep::Off;
    double marched_share = 1.0;  ///< the share of the internal pixels the march ran for
    /// Programs this frame compiled and linked (a variant the renderer had not used before). A
    /// software rasterizer also compiles each at its first draw, which can stall the frame for
    /// ~0.2-0.5 s without a shader cache (view::StormView::warm_up compiles them ahead).
    int programs_built = 0;
};

class Renderer {
public:
    /// Loads GL through `get_proc_address` (the context must be current) and compiles the
    /// shaders from `shader_dir`. Throws core::Error when GL 4.5 core is unavailable or a
    /// shader fails (the message names the shader file and line).
    explicit Renderer(GetProcAddress get_proc_address, std::filesystem::path shader_dir = default_shader_dir());
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    /// Uploads the density (full resolution) and derives the empty-space distance field.
    /// Throws core::Error for an invalid geometry or a null density.
    void set_volume(const VolumeDesc& volume);
    /// The share of the rain's extinction the ground's flash lights cross
    /// (VolumeDesc::rain_solved_share of the last set_volume; 1 when it held no rain).
    double rain_solved_share() const noexcept;
    /// VolumeDesc::rain_solved_share without uploading the volume again (the flash's solves
    /// changed). Throws core::Error unless finite and > 0; kept at 1 while the volume holds no
    /// rain. The temporal history is kept: a still camera marches it again a quarter a frame.
    void set_rain_solved_share(double share);
    /// No cloud: the march pass outputs T = 1 (the background is seen unchanged).
    void clear_volume();
    /// Uploads directions of S (see SourceUpload). Throws core::Error on inconsistent input
    /// (direction index out of range, wrong array size, invalid geometry, non-finite values).
    void upload_source(const SourceUpload& source);
    /// With rain (VolumeDesc::rain): the flash's light of orders >= 2 at the rain's points, per
    /// unit albedo, on its own grid (runtime::Frame::rain: the strikes solved with the rain in
    /// their media), validated and kept as upload_source's S. The rain's samples scatter it by
    /// the rain's albedo; its first order comes from the channel's point lights. It belongs to
    /// the flash's light group: the temporal history rescales it with the flash's S, and marches
    /// again where the two changed by different factors.
    void upload_rain_source(const SourceUpload& rain);
    /// No such light (the default; clear_source clears it too): the rain is lit by the channel's
    /// first order alone.
    void clear_rain_source();
    /// No light in the cloud (no active flash): the march skips S entirely.
    void clear_source();
    /// Uploads the static light (all directions; see StaticUpload). Throws core::Error on
    /// inconsistent input (naming the direction and value).
    void upload_static(const StaticUpload& light);
    /// No static light: the march does not sample it.
    void clear_static();
    /// The sun (see SunDesc). Throws core::Error on bad input or a transmittance on another
    /// grid than the volume's.
    void set_sun(const SunDesc& sun);
    void clear_sun();
    void set_channel(const LitChannel& bolt);
    /// Forgets the temporal history (Settings::temporal): the next frame marches every pixel,
    /// as the first frame does, and the frames after it take the same steps a new renderer's
    /// would. For a host that knows its camera cut or its scene changed, and after frames that
    /// are not shown (view::StormView::warm_up).
    void reset_history();

    /// Directions of S this camera needs (see view_directions), restricted to lighting nodes
    /// near non-empty density (all nodes before set_volume()). Pass the min_weight of the
    /// Settings the frame will use.
    std::vector<DirectionUse> needed_directions(const Camera& camera, const core::GridGeometry& lighting,
                                                int direction_count, double min_weight = kDirectionMinWeight) const;

    /// Renders one frame of size width x height into the currently bound draw framebuffer
    /// (sets the viewport to the full size; restores the framebuffer binding).
    FrameStats render(const Camera& camera, const Settings& settings, int width, int height);

    /// Composites the storm into a host engine's HDR target, bound as the draw framebuffer
    /// (width x height, float RGB): dst = L + T dst, with L the storm's radiance (the cloud's
    /// light, the glow and the channel's core, W m^-2 sr^-1 before any exposure) and T the
    /// cloud's transmittance, both along each pixel's ray up to the host's opaque depth (the
    /// cloud behind a mountain is not drawn; the channel's core and glow behind it neither).
    /// The host's tone map, exposure and glare apply afterwards; Fulgur draws no sky, stars or
    /// ground (settings.sky, ground, glare and the automatic exposure are ignored) and does
    /// not touch the target's alpha. Throws core::Error as camera_from_matrices does.
    FrameStats render_into_host(const HostFrame& host, const Settings& settings, int width, int height);

    /// The lit channel (set_channel) as `k` representative point lights, for a host that lights
    /// its own surfaces by the flash: each channel segment's power (intensity x length) dimmed
    /// by the cloud's transmittance straight down from its midpoint to `ground_height`, the
    /// channel split into k runs of equal dimmed power, each light at its run's dimmed-power-
    /// weighted centroid with the run's dimmed radiant intensity (W/sr, grey: times
    /// Settings::flash_colour). So the channel below the cloud's base keeps its light wherever
    /// its run's centroid lies (the lights the renderer's own ground uses). Empty when no
    /// channel is lit.
    struct FlashLight {
        glm::dvec3 position{0.0};
        double intensity = 0.0;
    };
    std::vector<FlashLight> flash_lights(int k, double ground_height);

    /// The last frame before tone mapping (radiance, RGB float, rows top to bottom).
    std::vector<float> read_hdr() const;
    /// The last frame's ray-march output at internal resolution: RGBA float (rgb in-scattered
    /// + attenuated glow radiance, a = transmittance), rows top to bottom.
    std::vector<float> read_march(int& width, int& height) const;

    /// The last frame's S toward the camera on the lighting grid (x fastest): what the ray
    /// march sampled. Empty when the last frame had no S. For tests and radiance views.
    std::vector<float> read_resolved_source() const;
    /// The flash's light at the rain toward the camera (upload_rain_source, read out
    /// geometrically between directions) at the same nodes, as the last frame sampled it.
    /// Empty when the last frame had none.
    std::vector<float> read_resolved_rain_source() const;
    /// The same for the static light (rgb per cell). Empty when the last frame had none.
    std::vector<float> read_resolved_static() const;

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::render
