// `fulgur-bench render`: the OpenGL renderer through OSMesa (Mesa llvmpipe) at 640x360.
//
// Scene: synthetic::storm() — a procedural cumulonimbus of 128x128x96 density voxels (100 m),
// a branching cloud-to-ground bolt whose channel lights it (S on the 32x32x24 lighting grid,
// 26 directions; the view needs a few), the camera of docs/images/render_synthetic.png.
// Rows (JSON lines):
//   case "march":  the ray-march pass (wall and process-CPU medians) for the fragment and the
//                  compute kernel, against the baseline measured in the same run: a plain
//                  fixed-step march of the same volume (same step, same samples per ray, no
//                  empty-space skipping, no early exit, no glow). samples = the plain march's
//                  sample count for the view; Msamples_per_s = samples / time.
//   case "frame":  whole frames (resolve with a moving camera, glow, march, bolt, composite)
//                  per internal scale, wall and CPU, fps.
//   case "step":   accuracy knobs (step length, density precision) against a fine reference:
//                  relative RMS error of the ray-march output (radiance and transmittance of
//                  every internal pixel) and the march time.
//   case "detail": sub-voxel detail (cloud/subvoxel.h, billows of 3 voxels, 4 octaves,
//                  strength 0.6) on the same volume: the march's time against the undetailed
//                  march at the same step in the same run (ratio), its error per step against
//                  the detailed reference at step 0.25 (and with the default limit of the step
//                  by the finest billows), and the error of drawing only the voxel means the
//                  solvers integrate (no per-sample erosion) against the same reference.
//   case "rain":   a rain shaft under the storm (25 mm/h, cloud::make_rain): the march's and the
//                  whole frame's CPU time against the dry storm in the same run (ratios).
//   case "demo":   whole frames as the demo draws them (glare, ground, sky, automatic exposure,
//                  internal scale 0.5, Timing::Off + glFinish) at 640x360, 1280x720 and
//                  1920x1080, the camera orbiting (1 degree a frame) or still, with the storm
//                  plain and with detail and rain (the flash's light at the rain uploaded too),
//                  through a return stroke's decay; today's
//                  renderer and the temporal history (Settings::temporal: its steps and its
//                  error against a fresh render of each frame, the frames timed in a row and
//                  then marched again afresh). Today's plain still camera at the same size is
//                  the baseline of each row (ratio). The rows without the history give the
//                  metered exposure's difference from metering every pixel (Settings::meter_stride).
//   case "static_grid": the static light on the lighting grid and on a 3x finer one: upload,
//                  resolve and frame of a moving camera (FULGUR_BENCH_STATIC_GRID=1: these alone).
//   FULGUR_BENCH_DEMO_WIDTH=W runs only the demo rows, at output width W (640, 1280 or 1920);
//   FULGUR_BENCH_DEMO_LIGHT=decay|leader|static only that light's of them.
//   FULGUR_BENCH_PASS_FINISH=1 times the demo rows' passes one by one (glFinish around each)
//   instead of with timer queries, which llvmpipe may charge to the wrong pass.
//   FULGUR_BENCH_DEMO_RAIN_SOURCE=0: the demo rows' rain without the flash's light at the rain
//   (its cost, against a run without it).
//   FULGUR_BENCH_DEMO_IMAGES=DIR also writes, for the orbiting rows with detail and rain during
//   a return stroke and between flashes marching a sixteenth, and the still camera's leader,
//   frame 6 marched afresh beside the history's and their difference (PNG in DIR).
// llvmpipe uses LP_NUM_THREADS threads (default: all cores); the row says how many.
#include "bench/bench.h"

#include "cloud/rain.h"
#include "cloud/subvoxel.h"

#include "core/core.h"
#include "platform/platform.h"
#include "render/render.h"
#include "support/synthetic_storm.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <string>
#include <thread>

#include <time.h>

namespace {

using namespace fulgur;

struct Medians {
    double wall = 0, cpu = 0;
};

template <class Get>
Medians run_frames(render::Renderer& r, render::Camera cam, render::Settings st, int w, int h, int frames, Get get,
                   bool move_camera = false) {
    std::vector<double> wall, cpu;
    for (int i = 0; i < frames; ++i) {
        st.frame_index = std::uint32_t(i);
        if (move_camera) cam.position.x += 1.0;  // forces the resolve pass every frame
        const render::FrameStats s = r.render(cam, st, w, h);
        wall.push_back(get(s.wall));
        cpu.push_back(get(s.cpu));
    }
    return {bench::median(wall), bench::median(cpu)};
}

/// Relative RMS error of the radiance (rgb) of two ray-march outputs (RGBA, a = T).
double radiance_rel_rms(const std::vector<float>& a, const std::vector<float>& ref) {
    core::CompensatedSum num, den;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (i % 4 == 3) continue;
        num.add(double(a[i] - ref[i]) * double(a[i] - ref[i]));
        den.add(double(ref[i]) * double(ref[i]));
    }
    return den.value() > 0.0 ? std::sqrt(num.value() / den.value()) : 0.0;
}

/// Pixel i (RGBA) of two march images as a viewer sees them: each radiance at `exposure`
/// through the composite's display transform (render::display_levels), and the largest channel
/// difference in 8-bit levels.
struct ShownPixel {
    std::array<int, 3> a, b;
    int diff = 0;
};
ShownPixel shown_pixel(const std::vector<float>& a, const std::vector<float>& b, std::size_t i, double exposure) {
    ShownPixel p{render::display_levels({a[4 * i], a[4 * i + 1], a[4 * i + 2]}, exposure),
                 render::display_levels({b[4 * i], b[4 * i + 1], b[4 * i + 2]}, exposure)};
    for (std::size_t c = 0; c < 3; ++c) p.diff = std::max(p.diff, std::abs(p.a[c] - p.b[c]));
    return p;
}

/// Two march images as a viewer sees them (shown_pixel): the largest channel difference's mean
/// over the pixels and the share of pixels more than 2 levels apart.
struct DisplayDiff {
    double mean_levels = 0.0, over_2 = 0.0;
};
DisplayDiff display_diff(const std::vector<float>& a, const std::vector<float>& ref, double exposure) {
    core::CompensatedSum sum;
    std::size_t over = 0;
    const std::size_t n = a.size() / 4;
    for (std::size_t i = 0; i < n; ++i) {
        const int d = shown_pixel(a, ref, i, exposure).diff;
        sum.add(double(d));
        over += d > 2;
    }
    return {n ? sum.value() / double(n) : 0.0, n ? double(over) / double(n) : 0.0};
}

/// Writes `path`: a fresh march, the history's march of the same frame and their difference
/// (x8, the largest channel's, in levels) side by side, each through the display transform
/// at `exposure` (the picture docs/render.md shows of a moving camera's frame).
void write_comparison(const std::filesystem::path& path, const std::vector<float>& fresh,
                      const std::vector<float>& kept, int w, int h, double exposure) {
    std::vector<std::uint8_t> px(std::size_t(3 * w) * std::size_t(h) * 4, 255);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const ShownPixel s = shown_pixel(fresh, kept, std::size_t(y) * std::size_t(w) + std::size_t(x), exposure);
            for (int panel = 0; panel < 3; ++panel) {
                const std::size_t out = (std::size_t(y) * std::size_t(3 * w) + std::size_t(panel * w + x)) * 4;
                for (std::size_t c = 0; c < 3; ++c)
                    px[out + c] = std::uint8_t(panel == 0 ? s.a[c] : panel == 1 ? s.b[c] : std::min(255, 8 * s.diff));
            }
        }
    core::write_png(path, 3 * w, h, 4, px);
}

/// Largest absolute transmittance difference.
double transmittance_max_err(const std::vector<float>& a, const std::vector<float>& ref) {
    double e = 0.0;
    for (std::size_t i = 3; i < a.size(); i += 4) e = std::max(e, std::abs(double(a[i]) - double(ref[i])));
    return e;
}

/// CPU time of the whole process (every llvmpipe thread), milliseconds.
double process_cpu_ms() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

int llvmpipe_threads() {
    if (const char* e = std::getenv("LP_NUM_THREADS"); e && *e) return std::atoi(e);
    return int(std::thread::hardware_concurrency());
}

}  // namespace

namespace {

// The detail of the "detail" and "demo" rows: billows of 3 voxels, 4 octaves, strength 0.6.
cloud::SubvoxelDetail bench_detail(double voxel) {
    cloud::SubvoxelDetail d;
    d.seed = 7;
    d.scale = 3.0 * voxel;
    d.octaves = 4;
    d.strength = 0.6;
    return d;
}

// The rain of the "rain" and "demo" rows: 25 mm/h, shear 400 m/km.
cloud::RainParams bench_rain() {
    cloud::RainParams r;
    r.rate = 25.0;
    r.shear = {400.0, 0.0};
    return r;
}

// A grey static light from the storm's S (x 1e-3, every direction) on its lighting grid refined
// `refine` times (each refined node takes its coarse node's S).
struct GreyStatic {
    core::GridGeometry geometry;
    std::vector<std::vector<float>> rgb;  // per direction, RGB per node
    render::StaticUpload upload() const {
        render::StaticUpload up;
        up.geometry = geometry;
        up.direction_count = int(rgb.size());
        for (const std::vector<float>& v : rgb) up.rgb.emplace_back(v.data(), v.size());
        return up;
    }
};

GreyStatic grey_static(const synthetic::Storm& storm, int refine) {
    const core::GridGeometry& lg = storm.lighting;
    const std::size_t coarse = lg.cell_count();
    GreyStatic out;
    out.geometry = lg;
    out.geometry.voxel_size = lg.voxel_size / refine;
    out.geometry.dims = {lg.dims.x * refine, lg.dims.y * refine, lg.dims.z * refine};
    const std::size_t cells = out.geometry.cell_count();
    out.rgb.assign(std::size_t(storm.directions), std::vector<float>(3 * cells));
    for (int m = 0; m < storm.directions; ++m)
        for (std::size_t c = 0; c < cells; ++c) {
            const core::Int3 n = out.geometry.unindex(c);
            const float v =
                1e-3f * storm.source[std::size_t(m) * coarse + lg.index(n.x / refine, n.y / refine, n.z / refine)];
            for (int ch = 0; ch < 3; ++ch) out.rgb[std::size_t(m)][3 * c + std::size_t(ch)] = v;
        }
    return out;
}

// The demo's frames at one output size: a context and renderer of that size (shaders
// compiled before timing), all 26 directions of S uploaded (the orbit needs others than the
// first view's), the storm plain or with detail and rain, a return stroke decaying over the
// frames (S and the channel scaled by exp(-frame / 8) before each, untimed, as the run time
// uploads them), today's renderer and the temporal history; then the same between flashes (a
// static light alone). Each temporal frame is compared with a fresh render of the same frame
// (untimed).
void demo_rows(const bench::Context& ctx, const synthetic::Storm& storm, const cloud::SubvoxelDetail& detail,
               const cloud::RainParams& rain_params, int frames) {
    const cloud::RainField rain = cloud::make_rain(storm.density, rain_params);
    const std::size_t cells = storm.lighting.cell_count();
    std::vector<float> scaled(storm.source.size());
    // With rain, the flash's light at the rain too (runtime::Frame::rain, uploaded by the run
    // time with its S): `scaled` again, the same grid and directions, as a stand-in of its cost.
    bool wet = false;
    // Uploads `scaled` as S in every direction.
    auto upload_scaled = [&](render::Renderer& r) {
        render::SourceUpload all;
        all.geometry = storm.lighting;
        all.direction_count = storm.directions;
        for (int m = 0; m < storm.directions; ++m) {
            all.directions.push_back(m);
            all.values.emplace_back(scaled.data() + std::size_t(m) * cells, cells);
        }
        r.upload_source(all);
        if (wet) r.upload_rain_source(all);
    };
    auto show_flash = [&](render::Renderer& r, double g) {
        for (std::size_t i = 0; i < scaled.size(); ++i) scaled[i] = float(double(storm.source[i]) * g);
        upload_scaled(r);
        render::LitChannel ch = storm.bolt;
        for (render::ChannelSegment& c : ch.segments) c.intensity = float(double(c.intensity) * g);
        r.set_channel(ch);
    };
    // A leader's frame: the channel lit above a front that descends over `n` frames from the
    // channel's top to its foot, and S weighted by the same front (whole above it, fading to 0
    // over 1 km below): the flash and the channel in a new shape every frame, as a stepped
    // leader or a new stroke's channel shows them.
    double top = -1e30, foot = 1e30;
    for (const render::ChannelSegment& c : storm.bolt.segments) {
        top = std::max({top, double(c.a.z), double(c.b.z)});
        foot = std::min({foot, double(c.a.z), double(c.b.z)});
    }
    auto show_leader = [&](render::Renderer& r, int i, int n) {
        const double front = top - (top - foot) * double(i + 1) / double(n);
        const auto weight = [&](double z) { return std::clamp(1.0 - (front - z) / 1000.0, 0.0, 1.0); };
        std::vector<double> w(cells);
        for (std::size_t c = 0; c < cells; ++c) {
            const core::Int3 v = storm.lighting.unindex(c);
            w[c] = 0.3 * weight(storm.lighting.centre(v.x, v.y, v.z).z);
        }
        for (std::size_t k = 0; k < scaled.size(); ++k) scaled[k] = float(double(storm.source[k]) * w[k % cells]);
        upload_scaled(r);
        render::LitChannel ch = storm.bolt;
        std::erase_if(ch.segments, [&](const render::ChannelSegment& c) { return std::min(c.a.z, c.b.z) < front; });
        for (render::ChannelSegment& c : ch.segments) c.intensity *= 0.3f;
        r.set_channel(ch);
    };
    const GreyStatic moonlit = grey_static(storm, 1);
    for (const core::Int3 size : {core::Int3{640, 360, 0}, core::Int3{1280, 720, 0}, core::Int3{1920, 1080, 0}}) {
        if (const char* only = std::getenv("FULGUR_BENCH_DEMO_WIDTH"); only && size.x != std::atoi(only)) continue;
        auto context = platform::create_headless({.width = size.x, .height = size.y});
        render::Renderer r(context->get_proc_address());
        render::Settings st = storm.settings;
        st.glare = true;
        st.auto_exposure = true;
        // Per-pass GPU times, read at the frame's end (timer queries; llvmpipe may count work
        // queued by one pass in the next that flushes it), or FULGUR_BENCH_PASS_FINISH=1: each
        // pass waited for (glFinish) and timed on the wall clock, exact per pass, the frame
        // serialized.
        st.timing = std::getenv("FULGUR_BENCH_PASS_FINISH") ? render::Timing::Finish : render::Timing::Queries;
        double baseline = 0.0;
        constexpr double kOrbitFov = 55.0;  // the orbiting camera's vertical field of view (degrees)
        // Whether the default (TemporalLight::Auto) fills an orbiting frame's pixels not marched
        // from the marched ones (else from the history, reprojected), a quarter or a sixteenth
        // marched alike.
        const int march_height = std::max(1, int(std::lround(size.y * st.internal_scale)));
        const bool auto_upsamples = render::temporal_upsamples(render::TemporalLight::Auto, kOrbitFov, march_height);
        // The block the default (temporal_moving_block 0) marches between flashes, orbiting.
        const int auto_block = render::temporal_block(0, kOrbitFov, march_height);
        // During a flash (the return stroke's decay; no static light), then between flashes:
        // the static light alone (the storm's S, x 1e-3, as a grey moonlit field on the
        // lighting grid), no flash S, no channel, so no glow, bolt or glare: what most of a
        // storm's frames draw.
        for (const int light : {0, 1, 2}) {
            // 0: a return stroke's decay (a flash changing in intensity only), 1: a leader
            // (changing in shape every frame), 2: between flashes.
            const bool flash = light < 2, leader = light == 1;
            // FULGUR_BENCH_DEMO_LIGHT: that light's rows alone.
            if (const char* only = std::getenv("FULGUR_BENCH_DEMO_LIGHT");
                only && std::string(only) != (leader  ? "leader"
                                              : flash ? "decay"
                                                      : "static"))
                continue;
            if (!flash) {
                r.clear_source();
                r.set_channel({});
                r.upload_static(moonlit.upload());
            }
            for (const bool effects : {false, true}) {
                const char* rain_source = std::getenv("FULGUR_BENCH_DEMO_RAIN_SOURCE");
                wet = effects && !(rain_source && std::string(rain_source) == "0");
                r.set_volume({.density = &storm.density,
                              .extinction = storm.extinction,
                              .detail = effects ? std::optional(detail) : std::nullopt,
                              .rain = effects ? &rain : nullptr});
                for (const bool orbit : {false, true})
                    for (const int mode : {0, 1, 2, 3, 4}) {
                        // 0 without the history, 1 with it (the default: the pixels not marched
                        // filled as TemporalLight::Auto picks), 2 with them filled the other way
                        // (reprojected where Auto upsamples, upsampled where it reprojects), 3
                        // the other block than the default's (between flashes a quarter where it
                        // marches a sixteenth, a sixteenth where it marches a quarter; during a
                        // return stroke a sixteenth, temporal_flash_block 4; filled as Auto picks):
                        // a moving camera's knobs only; 4 a leader's new shapes marched at every
                        // pixel (TemporalReshape::Full; mode 1: a quarter, the default).
                        const bool temporal = mode > 0;
                        if ((mode == 2 || mode == 3) && (!orbit || leader)) continue;
                        if (mode == 3 && leader) continue;  // a new shape marches a quarter either way
                        if (mode == 4 && !leader) continue;
                        std::vector<double> wall, cpu, error, jitter_noise, exposure, shown;
                        std::vector<double> display_mean, display_over2, display_noise_mean, display_noise_over2;
                        std::vector<render::PassTimes> passes;
                        int steps[4] = {0, 0, 0, 0};
                        st.temporal = temporal;
                        st.temporal_reshape =
                            mode == 4 ? render::TemporalReshape::Full : render::TemporalReshape::Quarter;
                        // The block a frame marches: by default a sixteenth only between flashes.
                        const int default_block = flash ? 2 : auto_block,
                                  block = mode == 3 ? 6 - default_block : default_block;
                        st.temporal_moving_block = mode == 3 ? block : 0;
                        st.temporal_flash_block = mode == 3 && flash ? 4 : 2;
                        const bool upsampled = mode == 2 ? !auto_upsamples : auto_upsamples;
                        st.temporal_light =
                            mode == 2 ? (upsampled ? render::TemporalLight::Upsample : render::TemporalLight::Reproject)
                                      : render::TemporalLight::Auto;
                        // Frame i (from -2: two frames to compile and fault pages in): its flash and camera.
                        auto show_frame = [&](int i) {
                            if (leader)
                                show_leader(r, i + 2, frames + 2);
                            else if (flash)
                                show_flash(r, std::exp(-(i + 2) / 8.0));
                            st.frame_index = std::uint32_t(i + 2);
                            return orbit ? synthetic::orbit_camera(storm, -60.0 + 1.0 * (i + 2), 8.0, kOrbitFov)
                                         : storm.camera;
                        };
                        // The frames in a row, as the demo draws them; the history's march of each kept.
                        std::vector<std::vector<float>> kept;
                        for (int i = -2; i < frames; ++i) {
                            const render::Camera cam = show_frame(i);
                            const double cpu0 = process_cpu_ms();
                            core::Stopwatch sw;
                            const render::FrameStats stats = r.render(cam, st, size.x, size.y);
                            context->present();  // glFinish
                            if (i < 0) continue;
                            wall.push_back(sw.milliseconds());
                            cpu.push_back(process_cpu_ms() - cpu0);
                            passes.push_back(stats.wall);
                            exposure.push_back(stats.metered_exposure);
                            shown.push_back(stats.exposure);
                            ++steps[int(stats.temporal)];
                            int w = 0, h = 0;
                            if (temporal) kept.push_back(r.read_march(w, h));
                        }
                        // Then each frame again, marched afresh, against the history's.
                        for (int i = 0; temporal && i < frames; ++i) {
                            const render::Camera cam = show_frame(i);
                            render::Settings fresh = st;
                            fresh.temporal = false;
                            r.render(cam, fresh, size.x, size.y);
                            int w = 0, h = 0;
                            const std::vector<float> fresh_march = r.read_march(w, h);
                            error.push_back(radiance_rel_rms(kept[std::size_t(i)], fresh_march));
                            const DisplayDiff shown_diff =
                                display_diff(kept[std::size_t(i)], fresh_march, shown[std::size_t(i)]);
                            // FULGUR_BENCH_DEMO_IMAGES=DIR: frame 6 with detail and rain of an orbit
                            // through a return stroke and of a still camera's leader (its new
                            // shapes a quarter at a time), fresh | the history's | difference.
                            const char* dir = std::getenv("FULGUR_BENCH_DEMO_IMAGES");
                            // Between flashes, the orbit's sixteenth too.
                            const bool picture =
                                orbit ? (flash && !leader) || (!flash && block == 4) : leader && mode == 1;
                            if (dir && picture && effects && i == 6)
                                write_comparison(
                                    std::filesystem::path(dir) /
                                        (leader   ? "demo-leader-" + std::to_string(size.x) + "-still.png"
                                         : !flash ? "demo-orbit-static-" + std::to_string(size.x) + "-sixteenth.png"
                                                  : "demo-orbit-" + std::to_string(size.x) + "-" +
                                                        (upsampled ? "upsample" : "reproject") + ".png"),
                                    fresh_march, kept[std::size_t(i)], w, h, shown[std::size_t(i)]);
                            display_mean.push_back(shown_diff.mean_levels);
                            display_over2.push_back(shown_diff.over_2);
                            // The jitter's own noise: the same frame marched with another frame's jitter.
                            fresh.frame_index += 2;
                            r.render(cam, fresh, size.x, size.y);
                            const std::vector<float> other = r.read_march(w, h);
                            jitter_noise.push_back(radiance_rel_rms(other, fresh_march));
                            const DisplayDiff noise_diff = display_diff(other, fresh_march, shown[std::size_t(i)]);
                            display_noise_mean.push_back(noise_diff.mean_levels);
                            display_noise_over2.push_back(noise_diff.over_2);
                        }
                        // Without the history: each frame's exposure metered at every pixel
                        // (Settings::meter_stride 1) against the timed frames' (the default).
                        std::vector<double> meter_stops;
                        for (int i = 0; !temporal && i < frames; ++i) {
                            const render::Camera cam = show_frame(i);
                            render::Settings every = st;
                            every.meter_stride = 1;
                            const double e1 = r.render(cam, every, size.x, size.y).metered_exposure;
                            meter_stops.push_back(std::abs(std::log2(exposure[std::size_t(i)] / e1)));
                        }
                        const double ms = bench::median(wall);
                        if (!effects && !orbit && !temporal) baseline = ms;
                        nlohmann::json row = {
                            {"case", "demo"},
                            {"size", {size.x, size.y}},
                            {"camera", orbit ? "orbit" : "still"},
                            {"flash", flash},
                            {"light", leader  ? "leader"
                                      : flash ? "decay"
                                              : "static"},
                            {"reshape", mode == 4 ? "full" : "quarter"},
                            {"effects", effects ? "detail+rain" : "none"},
                            {"temporal", temporal},
                            // A moving camera's pixels not marched: upsampled from the marched
                            // ones or reprojected from the history; and what the default does.
                            {"fill", orbit && temporal ? (upsampled ? "upsample" : "reproject") : "none"},
                            {"default_fill", auto_upsamples ? "upsample" : "reproject"},
                            // The block a moving camera marches (none for a still one): by default
                            // a sixteenth only between flashes (temporal_flash_block).
                            {"moving_block", orbit ? nlohmann::json(block) : nlohmann::json(nullptr)},
                            {"default_moving_block", orbit ? nlohmann::json(default_block) : nlohmann::json(nullptr)},
                            {"frame_ms", ms},
                            {"fps", 1000.0 / ms},
                            {"frame_cpu_ms", bench::median(cpu)},
                            {"baseline_frame_ms", baseline},
                            {"ratio", ms / baseline},
                            {"baseline",
                             "today's renderer (no temporal history), the plain storm, "
                             "still camera, same size, same run"}};
                        auto pass = [&](double render::PassTimes::*m) {
                            std::vector<double> v;
                            for (const render::PassTimes& t : passes) v.push_back(t.*m);
                            return bench::median(v);
                        };
                        row["pass_timing"] = st.timing == render::Timing::Finish ? "finish" : "queries";
                        row["pass_ms"] = {{"resolve", pass(&render::PassTimes::resolve)},
                                          {"glow", pass(&render::PassTimes::glow)},
                                          {"march", pass(&render::PassTimes::march)},
                                          {"meter", pass(&render::PassTimes::meter)},
                                          {"bolt", pass(&render::PassTimes::bolt)},
                                          {"glare", pass(&render::PassTimes::glare)},
                                          {"composite", pass(&render::PassTimes::composite)}};
                        if (!temporal) {
                            row["meter_stride"] = st.meter_stride;
                            row["meter_vs_every_pixel_stops_median"] = bench::median(meter_stops);
                            row["meter_vs_every_pixel_stops_max"] =
                                *std::max_element(meter_stops.begin(), meter_stops.end());
                        }
                        if (temporal) {
                            row["frames_full"] = steps[int(render::TemporalStep::Full)];
                            row["frames_quarter"] = steps[int(render::TemporalStep::Quarter)];
                            row["frames_reused"] = steps[int(render::TemporalStep::Reused)];
                            row["error_vs_fresh_median"] = bench::median(error);
                            row["error_vs_fresh_max"] = *std::max_element(error.begin(), error.end());
                            row["jitter_noise_median"] = bench::median(jitter_noise);
                            row["display_levels_mean_median"] = bench::median(display_mean);
                            row["display_over_2_levels_median"] = bench::median(display_over2);
                            row["display_jitter_noise_levels_mean_median"] = bench::median(display_noise_mean);
                            row["display_jitter_noise_over_2_levels_median"] = bench::median(display_noise_over2);
                            row["error"] =
                                "relative L2 of the march's radiance against a fresh render of the frame; "
                                "jitter_noise: a fresh render with another frame's jitter against it; display_*: "
                                "both marches at the frame's exposure through the display transform, the largest "
                                "channel difference in 8-bit levels per pixel, its mean and the share of pixels "
                                "over 2 levels (medians over the frames)";
                        }
                        ctx.emit("render", row);
                    }
            }
        }
        r.clear_static();
    }
}

// The static light (sun, moon, sky: StaticUpload) on the storm's lighting grid and on that
// grid refined 3x (transport.static_light.grid "transport" keeps it on the grid its solve ran
// on: 27x the nodes on the default storm): its upload, and the resolve and the whole frame of
// a moving camera (the resolve runs every frame), the flash lit as in the other rows. The
// field's values do not matter for the time: each refined node takes its coarse node's S.
void static_grid_rows(const bench::Context& ctx, render::Renderer& r, const synthetic::Storm& storm,
                      const render::Settings& base, int w, int h, int frames) {
    double baseline_resolve = 0.0, baseline_frame = 0.0;
    for (const int refine : {1, 3}) {
        const GreyStatic grey = grey_static(storm, refine);
        const std::size_t cells = grey.geometry.cell_count();
        const render::StaticUpload up = grey.upload();
        core::Stopwatch sw;
        r.upload_static(up);
        const double upload_ms = sw.milliseconds();
        r.render(storm.camera, base, w, h);  // the refined grid's node mask and first resolve
        const Medians resolve = run_frames(
            r, storm.camera, base, w, h, frames, [](const render::PassTimes& t) { return t.resolve; }, true);
        const Medians frame = run_frames(
            r, storm.camera, base, w, h, frames, [](const render::PassTimes& t) { return t.total; }, true);
        if (refine == 1) {
            baseline_resolve = resolve.cpu;
            baseline_frame = frame.cpu;
        }
        ctx.emit("render", {{"case", "static_grid"},
                            {"refine", refine},
                            {"static_nodes", cells},
                            {"upload_ms", upload_ms},
                            {"resolve_ms", resolve.wall},
                            {"resolve_cpu_ms", resolve.cpu},
                            {"frame_ms", frame.wall},
                            {"frame_cpu_ms", frame.cpu},
                            {"resolve_cpu_ratio", resolve.cpu / baseline_resolve},
                            {"frame_cpu_ratio", frame.cpu / baseline_frame},
                            {"baseline", "the static light on the lighting grid (refine 1), same run"}});
    }
    r.clear_static();
}

}  // namespace

FULGUR_BENCH(render, "GL renderer via OSMesa at 640x360: ray march vs plain fixed-step march, frame times, knobs") {
    const int W = 640, H = 360;
    const int frames = ctx.quick ? 3 : 9;
    auto context = platform::create_headless({.width = W, .height = H});
    const core::Int3 dims = ctx.quick ? core::Int3{64, 64, 48} : core::Int3{128, 128, 96};
    const double voxel = ctx.quick ? 200.0 : 100.0;
    const synthetic::Storm storm = synthetic::storm(dims, voxel);
    const core::Grid3<float>& density = storm.density;
    const double kappa = storm.extinction;
    const render::Camera& cam = storm.camera;
    if (std::getenv("FULGUR_BENCH_DEMO_WIDTH")) {  // the demo rows alone
        demo_rows(ctx, storm, bench_detail(voxel), bench_rain(), frames);
        return;
    }

    render::Renderer r(context->get_proc_address());
    r.set_volume({.density = &density, .extinction = kappa});
    r.set_channel(storm.bolt);
    // Upload only the directions this view needs, as the run time does.
    const render::SourceUpload up = synthetic::needed_upload(r, storm);
    core::Stopwatch upload_clock;
    r.upload_source(up);
    const double upload_ms = upload_clock.milliseconds();
    if (std::getenv("FULGUR_BENCH_STATIC_GRID")) {  // the static light's grid rows alone
        static_grid_rows(ctx, r, storm, storm.settings, W, H, frames);
        return;
    }

    const render::Settings base = storm.settings;  // defaults: internal scale 0.5, step 1 voxel, skipping, early exit
    const int iw = int(std::lround(W * base.internal_scale)), ih = int(std::lround(H * base.internal_scale));
    const double samples = render::plain_march_samples(cam, density.geom, iw, ih, base.step_voxels * voxel);
    auto march = [](const render::PassTimes& t) { return t.march; };

    for (render::MarchKernel kernel : {render::MarchKernel::Fragment, render::MarchKernel::Compute}) {
        render::Settings opt = base, plain = base;
        opt.kernel = plain.kernel = kernel;
        plain.skip_empty = false;
        plain.early_exit = false;
        plain.glow = false;
        r.render(cam, opt, W, H);  // JIT compile (llvmpipe compiles shaders at first use)
        r.render(cam, plain, W, H);
        // Interleave the two so both see the same machine load.
        std::vector<double> ow, oc, pw, pc;
        for (int rep = 0; rep < 3; ++rep) {
            const Medians o = run_frames(r, cam, opt, W, H, frames, march);
            const Medians p = run_frames(r, cam, plain, W, H, frames, march);
            ow.push_back(o.wall);
            oc.push_back(o.cpu);
            pw.push_back(p.wall);
            pc.push_back(p.cpu);
        }
        const double o_wall = bench::median(ow), o_cpu = bench::median(oc), p_wall = bench::median(pw),
                     p_cpu = bench::median(pc);
        // The same pass timed by GL timer queries (does the driver's clock agree?).
        render::Settings q = opt;
        q.timing = render::Timing::Queries;
        const Medians tq = run_frames(r, cam, q, W, H, frames, march);
        ctx.emit("render", {{"case", "march"},
                            {"kernel", kernel == render::MarchKernel::Fragment ? "fragment" : "compute"},
                            {"size", {W, H}},
                            {"internal", {iw, ih}},
                            {"volume", {dims.x, dims.y, dims.z}},
                            {"step_voxels", base.step_voxels},
                            {"samples", samples},
                            {"march_ms", o_wall},
                            {"march_cpu_ms", o_cpu},
                            {"march_ms_timer_query", tq.wall},
                            {"plain_march_ms", p_wall},
                            {"plain_march_cpu_ms", p_cpu},
                            {"Msamples_per_s", samples / o_wall * 1e-3},
                            {"plain_Msamples_per_s", samples / p_wall * 1e-3},
                            {"ratio_vs_plain", p_wall / o_wall},
                            {"ratio_vs_plain_cpu", p_cpu / o_cpu},
                            {"llvmpipe_threads", llvmpipe_threads()}});
    }

    // Whole frames with a moving camera (the resolve runs every frame), per internal scale.
    for (double scale : {0.5, 0.75, 1.0}) {
        render::Settings st = base;
        st.internal_scale = scale;
        r.render(cam, st, W, H);
        std::vector<double> wall, cpu, resolve, glow, mar, bolt_ms, comp, resolve_cpu, march_cpu, comp_cpu;
        int glow_quads = 0;
        render::Camera c = cam;
        for (int i = 0; i < frames; ++i) {
            st.frame_index = std::uint32_t(i);
            c.position.x += 1.0;
            const render::FrameStats s = r.render(c, st, W, H);
            wall.push_back(s.wall.total);
            cpu.push_back(s.cpu.total);
            resolve.push_back(s.wall.resolve);
            glow.push_back(s.wall.glow);
            mar.push_back(s.wall.march);
            bolt_ms.push_back(s.wall.bolt);
            comp.push_back(s.wall.composite);
            resolve_cpu.push_back(s.cpu.resolve);
            march_cpu.push_back(s.cpu.march);
            comp_cpu.push_back(s.cpu.composite);
            glow_quads = s.glow_quads;
        }
        // Without per-pass glFinish (Timing::Off + one glFinish): what the demo sees.
        render::Settings fast = st;
        fast.timing = render::Timing::Off;
        std::vector<double> off;
        for (int i = 0; i < frames; ++i) {
            fast.frame_index = std::uint32_t(i);
            c.position.x += 1.0;
            core::Stopwatch sw;
            r.render(c, fast, W, H);
            context->present();  // glFinish
            off.push_back(sw.milliseconds());
        }
        const double frame_ms = bench::median(off);
        ctx.emit("render", {{"case", "frame"},
                            {"internal_scale", scale},
                            {"frame_ms", frame_ms},
                            {"fps", 1000.0 / frame_ms},
                            {"timed_frame_ms", bench::median(wall)},
                            {"timed_frame_cpu_ms", bench::median(cpu)},
                            {"resolve_ms", bench::median(resolve)},
                            {"glow_ms", bench::median(glow)},
                            {"march_ms", bench::median(mar)},
                            {"bolt_ms", bench::median(bolt_ms)},
                            {"composite_ms", bench::median(comp)},
                            {"resolve_cpu_ms", bench::median(resolve_cpu)},
                            {"march_cpu_ms", bench::median(march_cpu)},
                            {"composite_cpu_ms", bench::median(comp_cpu)},
                            {"upload_ms", upload_ms},
                            {"directions_uploaded", up.directions.size()},
                            {"glow_quads", glow_quads},
                            {"llvmpipe_threads", llvmpipe_threads()}});
    }

    // Accuracy knobs against a fine reference (step 1/4 voxel, F16 density, no jitter so the
    // comparison measures bias rather than noise).
    render::Settings ref = base;
    ref.step_voxels = 0.25;
    ref.jitter = false;
    ref.dither = false;
    r.set_volume({.density = &density, .extinction = kappa, .precision = render::DensityPrecision::F16});
    int mw = 0, mh = 0;
    r.render(cam, ref, W, H);
    const std::vector<float> reference = r.read_march(mw, mh);
    for (auto precision : {render::DensityPrecision::F16, render::DensityPrecision::U8}) {
        r.set_volume({.density = &density, .extinction = kappa, .precision = precision});
        for (double step : {0.5, 1.0, 2.0}) {
            render::Settings st = ref;
            st.step_voxels = step;
            r.render(cam, st, W, H);
            const std::vector<float> img = r.read_march(mw, mh);
            const Medians t = run_frames(r, cam, st, W, H, frames, march);
            ctx.emit("render", {{"case", "step"},
                                {"density", precision == render::DensityPrecision::U8 ? "u8" : "f16"},
                                {"step_voxels", step},
                                {"march_ms", t.wall},
                                {"march_cpu_ms", t.cpu},
                                {"radiance_rel_rms_error", radiance_rel_rms(img, reference)},
                                {"transmittance_max_error", transmittance_max_err(img, reference)},
                                {"reference", "step 0.25 voxel, f16 density, no jitter"}});
        }
    }

    // Sub-voxel detail: cost and accuracy of the per-sample erosion.
    const cloud::SubvoxelDetail detail = bench_detail(voxel);
    r.set_volume(
        {.density = &density, .extinction = kappa, .precision = render::DensityPrecision::F16, .detail = detail});
    r.render(cam, ref, W, H);
    const std::vector<float> detailed_ref = r.read_march(mw, mh);
    // Rows: the step alone (no limit from the billows), then the default settings (step 1,
    // at most 2 of the finest billows: here 0.75 voxel).
    for (double step : {0.5, 0.75, 1.0, 2.0, -1.0}) {
        render::Settings st = ref;
        const bool limited = step < 0.0;
        st.step_voxels = limited ? 1.0 : step;
        st.detail_step_billows = limited ? render::Settings{}.detail_step_billows : 0.0;
        r.set_volume({.density = &density, .extinction = kappa, .detail = detail});
        r.render(cam, st, W, H);
        const std::vector<float> img = r.read_march(mw, mh);
        const Medians with = run_frames(r, cam, st, W, H, frames, march);
        r.set_volume({.density = &density, .extinction = kappa});
        const Medians without = run_frames(r, cam, st, W, H, frames, march);
        ctx.emit("render", {{"case", "detail"},
                            {"density", "u8"},
                            {"step_voxels", st.step_voxels},
                            {"detail_step_billows", st.detail_step_billows},
                            {"march_ms", with.wall},
                            {"march_cpu_ms", with.cpu},
                            {"baseline_march_cpu_ms", without.cpu},
                            {"cpu_ratio", with.cpu / without.cpu},
                            {"radiance_rel_rms_error", radiance_rel_rms(img, detailed_ref)},
                            {"transmittance_max_error", transmittance_max_err(img, detailed_ref)},
                            {"baseline", "the same march without detail"},
                            {"reference", "detail on, step 0.25 voxel, f16 density, no jitter"}});
    }
    // The voxel means alone (what the bake, the truth and the sun integrate), drawn without
    // erosion per sample, against the detailed reference: what structure finer than a voxel
    // adds to the picture.
    const core::Grid3<float> means = cloud::detailed_density(density, cloud::DetailNoise(detail));
    r.set_volume({.density = &means, .extinction = kappa, .precision = render::DensityPrecision::F16});
    r.render(cam, ref, W, H);
    const std::vector<float> img = r.read_march(mw, mh);
    ctx.emit("render", {{"case", "detail_voxel_means"},
                        {"step_voxels", ref.step_voxels},
                        {"radiance_rel_rms_error", radiance_rel_rms(img, detailed_ref)},
                        {"transmittance_max_error", transmittance_max_err(img, detailed_ref)},
                        {"reference", "detail on, step 0.25 voxel, f16 density, no jitter"}});

    // Rain: what drawing it costs (the march's fetch is the same; the rain's light per sample
    // inside the shaft and the ground's shadow are the extra work).
    const cloud::RainParams rain_params = bench_rain();
    const cloud::RainField rain = cloud::make_rain(density, rain_params);
    auto whole = [](const render::PassTimes& t) { return t.total; };
    render::Settings st = base;
    st.ground = true;
    r.set_volume({.density = &density, .extinction = kappa});
    const Medians dry_march = run_frames(r, cam, st, W, H, frames, march, true);
    const Medians dry_frame = run_frames(r, cam, st, W, H, frames, whole, true);
    r.set_volume({.density = &density, .extinction = kappa, .rain = &rain});
    const Medians wet_march = run_frames(r, cam, st, W, H, frames, march, true);
    const Medians wet_frame = run_frames(r, cam, st, W, H, frames, whole, true);
    ctx.emit("render", {{"case", "rain"},
                        {"rate_mm_h", rain_params.rate},
                        {"march_cpu_ms", wet_march.cpu},
                        {"baseline_march_cpu_ms", dry_march.cpu},
                        {"march_cpu_ratio", wet_march.cpu / dry_march.cpu},
                        {"frame_cpu_ms", wet_frame.cpu},
                        {"baseline_frame_cpu_ms", dry_frame.cpu},
                        {"frame_cpu_ratio", wet_frame.cpu / dry_frame.cpu},
                        {"frame_ms", wet_frame.wall},
                        {"baseline_frame_ms", dry_frame.wall},
                        {"baseline", "the same storm without rain"}});

    static_grid_rows(ctx, r, storm, base, W, H, frames);
    demo_rows(ctx, storm, detail, rain_params, frames);
}
